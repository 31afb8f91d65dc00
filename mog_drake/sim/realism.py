"""A simulated cell that is not the planner's model: the differences a real cell has, each from
a named source, drawn once per run from a seed (docs/physics.md states every range and why).

The planner's model (the picking check, perception's camera, the controller's kinematics)
keeps the nominal values; only the station's world takes the draws, so nothing of them
reaches planning except through the images.

* camera: an extrinsic calibration error, the rendering camera's pose off the one perception
  assumes (``camera_offset`` m and ``camera_tilt_deg`` per axis, normal);
* depth: per-pixel noise on every depth image at ``depth_noise`` times the RealSense D435's
  RMS error at its distance (`d435_rms`), holes (``depth_holes``) and flying pixels
  (``flying_pixels``), fresh in each image (`depth_artefacts`);
* objects: each one's mass and its own friction (which Drake combines with the finger's and
  the other objects') times U(1 - s, 1 + s);
* table and fingers: their friction times U(1 - s, 1 + s), once per run;
* arm: the tool centre point ``tcp_offset`` m off in the palm's plane (normal, per axis);
* perception: each object seen off its true pose by its own ``pose_error`` m and
  ``yaw_error_deg`` (normal; a pose estimator's error, fixed for the object);
* objects' make: each outline offset by U(-``size_error``, ``size_error``) m;
* gripper: its grip force times U(1 - s, 1 + s) (``grip_force_spread``), once per run.

No Drake import: the station applies the draws.
"""

from dataclasses import dataclass

import numpy as np

from mog_drake.config import in_range
from mog_drake.errors import MogError

# The D435's depth RMS error, from Intel's D400 tuning guide (RMS = z^2 * subpixel / (f * B)):
# subpixel 0.08 (the guide's typical value), baseline B = 50 mm, and f = 447 px, its depth
# camera's focal length at 848 x 480 over an 87 deg horizontal field of view.
D435_SUBPIXEL, D435_BASELINE, D435_FOCAL_PX = 0.08, 0.050, 447.0


def d435_rms(z):
    """The D435's depth RMS error (m) at distance ``z`` (m): 2.3 mm at the camera's 0.8 m."""
    return np.asarray(z) ** 2 * D435_SUBPIXEL / (D435_FOCAL_PX * D435_BASELINE)


# A stereo depth camera's artefacts besides its noise (`depth_artefacts`). A pixel at a depth
# step of more than FLY_JUMP (m) is an edge pixel. A hole is likelier on a dark surface (x up to
# 1 + HOLE_DARK) and a steep one (x up to 1 + HOLE_STEEP): both return less of the projector's
# pattern to the imagers (Intel's D400 tuning guide: low texture and low reflectivity lower the
# fill rate; surfaces seen at grazing angles do too). The multipliers are this model's choice,
# not measured: they shape where holes fall, ``depth_holes`` sets how many.
FLY_JUMP = 0.010
HOLE_DARK, HOLE_STEEP = 3.0, 3.0


def depth_artefacts(
    z: np.ndarray,
    rgb: np.ndarray,
    rng: np.random.Generator,
    *,
    noise: float = 0.0,
    holes: float = 0.0,
    flying: float = 0.0,
    fx: float = D435_FOCAL_PX,
) -> np.ndarray:
    """A rendered depth image (H, W; m, nan or inf where nothing is seen) as a stereo depth
    camera delivers it (a copy, float32); ``rgb`` the colour image of the same view, ``fx``
    the image's focal length (px).

    1. Flying pixels: with probability ``flying``, a pixel on either side of a depth step
       takes a depth drawn uniformly between its own and its neighbour's across the step (a
       stereo matching window straddling the edge mixes both surfaces).
    2. Holes (nan), when ``holes`` > 0: every pixel the camera's right imager cannot see
       (stereo occlusion: a pixel whose neighbour at k columns to its right is nearer by k or
       more pixels of disparity, f B / z, B the D435's 50 mm baseline), and each other pixel
       with probability ``holes``, more on dark and steep surfaces (HOLE_DARK, HOLE_STEEP).
    3. Noise: ``noise`` times the D435's RMS error at each pixel's depth (`d435_rms`)."""
    z = np.array(z, dtype=np.float32)
    ok = np.isfinite(z)
    zf = np.where(ok, z, np.float32(np.inf))
    if flying > 0 or holes > 0:
        # The largest step to a 4-neighbour, and that neighbour's depth.
        step = np.zeros(z.shape, np.float32)
        other = z.copy()
        for axis, shift in ((0, 1), (0, -1), (1, 1), (1, -1)):
            n = np.roll(zf, shift, axis=axis)
            with np.errstate(invalid="ignore"):  # inf - inf: nothing seen on either side
                d = np.abs(n - zf)
            d[~np.isfinite(d)] = 0.0
            edge = [slice(None)] * 2
            edge[axis] = slice(0, 1) if shift > 0 else slice(-1, None)
            d[tuple(edge)] = 0.0  # np.roll wraps: no step across the image's border
            bigger = d > step
            step = np.where(bigger, d, step)
            other = np.where(bigger, n, other)
        at_edge = step > FLY_JUMP
    if flying > 0:
        fly = at_edge & (rng.random(z.shape) < flying)
        z[fly] += (rng.random(int(fly.sum())) * (other[fly] - z[fly])).astype(np.float32)
    if holes > 0:
        disparity = np.where(ok, fx * D435_BASELINE / np.where(ok, zf, 1.0), 0.0)
        reach = int(min(np.ceil(disparity.max() - disparity[ok].min()) if ok.any() else 0, 30))
        hidden = np.zeros(z.shape, bool)
        for k in range(1, reach + 1):
            hidden[:, :-k] |= disparity[:, k:] - disparity[:, :-k] >= k
        bright = np.asarray(rgb)[..., :3].max(axis=-1) / 255.0
        # The surface's slope: the depth step to a neighbour over the pixel's footprint (z / fx).
        steep = np.clip(step * fx / np.where(ok, zf, 1.0), 0.0, 1.0)
        p = holes * (1 + HOLE_DARK * (1 - bright)) * (1 + HOLE_STEEP * steep)
        z[hidden | (rng.random(z.shape) < p)] = np.nan
    if noise > 0:
        good = np.isfinite(z)
        sigma = noise * d435_rms(z[good])
        z[good] += (rng.standard_normal(sigma.shape) * sigma).astype(np.float32)
    return z


# Each difference of the world from the model, and the most it may be set to.
REALISM_LIMITS = {
    "camera_offset": 0.05,
    "camera_tilt_deg": 5.0,
    "depth_noise": 10.0,
    "depth_holes": 0.5,
    "flying_pixels": 1.0,
    "mass_spread": 0.9,
    "friction_spread": 0.9,
    "finger_friction_spread": 0.9,
    "table_friction_spread": 0.9,
    "tcp_offset": 0.02,
    "pose_error": 0.02,
    "yaw_error_deg": 10.0,
    "size_error": 0.003,
    "grip_force_spread": 0.9,
}


@dataclass
class RealismConfig:
    """How far the simulated world is from the planner's model (0 everywhere: the ideal cell,
    world and model the same). Spreads are relative half-widths of uniform draws."""

    # The draws' seed; each table's world is drawn from it and the table's own seed, so every
    # mode run on a table meets the same world, and another table another.
    seed: int = 0
    camera_offset: float = 0.0  # m, normal per axis: the camera's position error
    camera_tilt_deg: float = 0.0  # deg, normal per axis: its orientation error
    depth_noise: float = 0.0  # times the D435's RMS depth error at each pixel's distance
    # The share of pixels with no depth on a bright surface facing the camera (more on dark and
    # steep ones), and with it the stereo occlusion at every depth step (`depth_artefacts`).
    depth_holes: float = 0.0
    flying_pixels: float = 0.0  # the probability that a pixel at a depth step mixes both sides
    mass_spread: float = 0.0  # each object's mass x U(1 - s, 1 + s)
    friction_spread: float = 0.0  # each object's friction coefficient x U(1 - s, 1 + s)
    finger_friction_spread: float = 0.0  # the jaws' pads, once per run
    table_friction_spread: float = 0.0  # the table's surface, once per run
    tcp_offset: float = 0.0  # m, normal per horizontal axis of the palm: the tool centre point
    # Each object's pose as the camera sees it, off its true pose by a draw of its own (normal,
    # per horizontal axis and in yaw) that stays with the object: a pose estimator's error on
    # that object, apart from the calibration every object shares.
    pose_error: float = 0.0  # m
    yaw_error_deg: float = 0.0  # deg
    size_error: float = 0.0  # m: each object's outline offset by U(-s, s) from the library's
    grip_force_spread: float = 0.0  # the gripper's grip force x U(1 - s, 1 + s), once per run

    @property
    def enabled(self) -> bool:
        return any(getattr(self, k) > 0 for k in REALISM_LIMITS)

    def check(self) -> None:
        for key, most in REALISM_LIMITS.items():
            in_range(getattr(self, key), f"realism.{key}", 0, most, lo_open=False)
        if self.seed < 0:
            raise MogError(f"realism.seed must be >= 0, got {self.seed}")

    def draw(self, table_seed: int, n_objects: int) -> "World":
        """The world of one run on the table of seed ``table_seed`` with ``n_objects``."""
        rng = np.random.default_rng([self.seed, table_seed, 0x5EA1])

        def spread(s: float, n=None):
            return rng.uniform(1 - s, 1 + s, n) if s > 0 else (np.ones(n) if n else 1.0)

        return World(
            camera_offset=rng.normal(0.0, 1.0, 3) * self.camera_offset,
            camera_tilt=np.radians(rng.normal(0.0, 1.0, 3) * self.camera_tilt_deg),
            mass=spread(self.mass_spread, n_objects),
            friction=spread(self.friction_spread, n_objects),
            finger_friction=float(spread(self.finger_friction_spread)),
            table_friction=float(spread(self.table_friction_spread)),
            tcp_offset=np.append(rng.normal(0.0, 1.0, 2) * self.tcp_offset, 0.0),
            depth_noise=self.depth_noise,
            depth_holes=self.depth_holes,
            flying_pixels=self.flying_pixels,
            noise_seed=(self.seed, table_seed),
            # (Drawn after the draws above, which keep the values they had before these existed.)
            pose_offset=np.column_stack(
                [
                    rng.normal(0.0, 1.0, (n_objects, 2)) * self.pose_error,
                    np.radians(rng.normal(0.0, 1.0, n_objects) * self.yaw_error_deg),
                ]
            ),
            size_offset=rng.uniform(-1.0, 1.0, n_objects) * self.size_error,
            grip_force=float(spread(self.grip_force_spread)),
        )


@dataclass
class World:
    """One run's draws (scales multiply the nominal values)."""

    camera_offset: np.ndarray  # m, in the camera's parent (world) frame
    camera_tilt: np.ndarray  # rad, roll-pitch-yaw applied in the camera's own frame
    mass: np.ndarray  # per object
    friction: np.ndarray  # per object
    finger_friction: float
    table_friction: float
    tcp_offset: np.ndarray  # m, in the palm frame
    depth_noise: float
    depth_holes: float
    flying_pixels: float
    noise_seed: tuple
    pose_offset: np.ndarray  # per object (dx, dy, dyaw) in its own frame: where the camera sees it
    size_offset: np.ndarray  # per object, m: its outline's offset from the library's
    grip_force: float  # times the gripper's force setting

    @property
    def depth_artefacts(self) -> bool:
        return self.depth_noise > 0 or self.depth_holes > 0 or self.flying_pixels > 0

    def depth_rng(self, t: float) -> np.random.Generator:
        """The noise of the image taken at simulated time ``t``: the same image (a render
        evaluated again) gets the same noise, the next image new noise."""
        return np.random.default_rng([*self.noise_seed, int(round(t * 1e4))])


def seen_in_body(R_WB: np.ndarray, offset) -> tuple[np.ndarray, np.ndarray]:
    """Where the camera sees an object off its true pose by ``offset`` = (dx, dy, dyaw), a pose
    estimator's error in the table's plane, as a pose in the object's body frame: (R_BG, p_BG)
    for its perception geometry, the body at orientation ``R_WB`` (3 x 3). The shift lies in
    the table's plane whichever way up the object lies, along the body's heading (the yaw of
    its x axis, or of its y axis less 90 deg when x stands up), and the turn is about the
    vertical. For an object as the scene put it (body z up) this is (Rz(dyaw), (dx, dy, 0)): the
    error in its own frame. Registered once in the body frame, a bar knocked onto its side
    would carry dy along its vertical axis and be seen under the table or above its top."""
    R = np.asarray(R_WB, float)
    dx, dy, dyaw = (float(v) for v in offset)
    if abs(R[2, 0]) < 0.7:
        psi = np.arctan2(R[1, 0], R[0, 0])
    else:
        psi = np.arctan2(R[1, 1], R[0, 1]) - np.pi / 2
    c, s = np.cos(psi), np.sin(psi)
    shift = np.array([c * dx - s * dy, s * dx + c * dy, 0.0])
    cz, sz = np.cos(dyaw), np.sin(dyaw)
    Rz = np.array([[cz, -sz, 0.0], [sz, cz, 0.0], [0.0, 0.0, 1.0]])
    return R.T @ Rz @ R, R.T @ shift
