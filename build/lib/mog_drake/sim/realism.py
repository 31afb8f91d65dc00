"""A simulated cell that is not the planner's model: the differences a real cell has, each from
a named source, drawn once per run from a seed (docs/physics.md states every range and why).

The planner's model (the picking check, perception's camera, the controller's kinematics)
keeps the nominal values; only the station's world takes the draws, so nothing of them
reaches planning except through the images.

* camera: an extrinsic calibration error, the rendering camera's pose off the one perception
  assumes (``camera_offset`` m and ``camera_tilt_deg`` per axis, normal);
* depth: per-pixel noise on every depth image at ``depth_noise`` times the RealSense D435's
  RMS error at its distance (`d435_rms`), fresh in each image;
* objects: each one's mass and its own friction (which Drake combines with the finger's and
  the other objects') times U(1 - s, 1 + s);
* table and fingers: their friction times U(1 - s, 1 + s), once per run;
* arm: the tool centre point ``tcp_offset`` m off in the palm's plane (normal, per axis).

No Drake import: the station applies the draws.
"""

import math
from dataclasses import dataclass

import numpy as np

from mog_drake.errors import MogError

# The D435's depth RMS error, from Intel's D400 tuning guide (RMS = z^2 * subpixel / (f * B)):
# subpixel 0.08 (the guide's typical value), baseline B = 50 mm, and f = 447 px, its depth
# camera's focal length at 848 x 480 over an 87 deg horizontal field of view.
D435_SUBPIXEL, D435_BASELINE, D435_FOCAL_PX = 0.08, 0.050, 447.0


def d435_rms(z):
    """The D435's depth RMS error (m) at distance ``z`` (m): 2.3 mm at the camera's 0.8 m."""
    return np.asarray(z) ** 2 * D435_SUBPIXEL / (D435_FOCAL_PX * D435_BASELINE)


# Each difference of the world from the model, and the most it may be set to.
REALISM_LIMITS = {
    "camera_offset": 0.05,
    "camera_tilt_deg": 5.0,
    "depth_noise": 10.0,
    "mass_spread": 0.9,
    "friction_spread": 0.9,
    "finger_friction_spread": 0.9,
    "table_friction_spread": 0.9,
    "tcp_offset": 0.02,
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
    mass_spread: float = 0.0  # each object's mass x U(1 - s, 1 + s)
    friction_spread: float = 0.0  # each object's friction coefficient x U(1 - s, 1 + s)
    finger_friction_spread: float = 0.0  # the jaws' pads, once per run
    table_friction_spread: float = 0.0  # the table's surface, once per run
    tcp_offset: float = 0.0  # m, normal per horizontal axis of the palm: the tool centre point

    @property
    def enabled(self) -> bool:
        return any(getattr(self, k) > 0 for k in REALISM_LIMITS)

    def check(self) -> None:
        for key, most in REALISM_LIMITS.items():
            v = getattr(self, key)
            if not (math.isfinite(v) and 0 <= v <= most):
                raise MogError(f"realism.{key} must be in [0, {most:g}], got {v}")
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
            noise_seed=(self.seed, table_seed),
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
    noise_seed: tuple

    def depth_rng(self, t: float) -> np.random.Generator:
        """The noise of the image taken at simulated time ``t``: the same image (a render
        evaluated again) gets the same noise, the next image new noise."""
        return np.random.default_rng([*self.noise_seed, int(round(t * 1e4))])
