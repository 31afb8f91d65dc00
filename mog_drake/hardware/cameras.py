"""RGB-D cameras as LeafSystems with the simulated camera's ports: recorded frames from disk
(`ReplayCamera`: offline runs, tests; `record_frame` writes them) or an Intel RealSense
(`RealSenseCamera`, pyrealsense2)."""

from __future__ import annotations

import io
import warnings
from pathlib import Path

import numpy as np
from pydrake.common.value import AbstractValue
from pydrake.systems.framework import LeafSystem
from pydrake.systems.sensors import ImageDepth32F, ImageRgba8U

from mog_drake.errors import HardwareFault, MogError
from mog_drake.files import read_bytes

# A recorded frame is about 2 MB (640 x 480 RGB and float32 depth, compressed or not); a
# camera of 8192 x 8192 pixels (the scenario's most) about 470 MB.
FRAME_BYTES = 512 * 2**20


def _rgba(rgb: np.ndarray) -> ImageRgba8U:
    h, w = rgb.shape[:2]
    img = ImageRgba8U(w, h)
    img.mutable_data[:, :, :3] = rgb[:, :, :3]
    img.mutable_data[:, :, 3] = 255 if rgb.shape[2] == 3 else rgb[:, :, 3]
    return img


def _depth(depth: np.ndarray) -> ImageDepth32F:
    h, w = depth.shape[:2]
    img = ImageDepth32F(w, h)
    img.mutable_data[:, :, 0] = depth.reshape(h, w)
    return img


def _intrinsics(values, where: str) -> tuple[float, float, float, float]:
    """(fx, fy, cx, cy) from a sequence of four numbers, focal lengths positive."""
    k = np.asarray(values, float).ravel()
    if k.shape != (4,) or not np.all(np.isfinite(k)) or k[0] <= 0 or k[1] <= 0:
        raise MogError(f"{where}: intrinsics must be (fx, fy, cx, cy) with fx, fy > 0, got {k.tolist()}")
    return tuple(float(v) for v in k)


class ReplayCamera(LeafSystem):
    """Plays recorded RGB-D frames (frame_*.npz with `rgb` uint8, `depth` float32 in m and
    `intrinsics` (fx, fy, cx, cy) of the camera that took them, see `record_frame`), one per
    ``frame_period`` seconds, the last one held. Same ports as the simulated camera; its
    ``intrinsics`` are the frames' own. Frames recorded without intrinsics are read with
    ``fallback_intrinsics`` (the scenario's camera), with a warning; without a fallback they
    are refused."""

    def __init__(self, folder: str, frame_period: float = 1e9, fallback_intrinsics=None):
        super().__init__()
        files = sorted(Path(folder).glob("frame_*.npz"))
        if not files:
            raise MogError(f"no recorded frames (frame_*.npz) in {folder}")
        self._frames = []
        found = set()
        for f in files:
            data = read_bytes(f, "recorded frame (frame_*.npz)", FRAME_BYTES)
            try:
                d = np.load(io.BytesIO(data))
                if "rgb" not in d or "depth" not in d:
                    raise MogError(f"{f}: a frame needs arrays 'rgb' and 'depth'")
                rgb, depth = np.asarray(d["rgb"]), np.asarray(d["depth"], np.float32)
                k = _intrinsics(d["intrinsics"], str(f)) if "intrinsics" in d else None
            except MogError:
                raise
            except Exception as e:  # unreadable, truncated, not an npz
                raise MogError(f"{f}: not a readable frame ({type(e).__name__}: {e})") from None
            if rgb.ndim != 3 or rgb.shape[2] not in (3, 4) or depth.shape[:2] != rgb.shape[:2]:
                raise MogError(
                    f"{f}: rgb must be (H, W, 3 or 4) and depth (H, W), got {rgb.shape} and {depth.shape}"
                )
            found.add(k)
            self._frames.append((_rgba(rgb), _depth(depth)))
        if len(found) > 1:
            raise MogError(f"{folder}: the frames were recorded with different intrinsics (or some without)")
        if None in found:
            if fallback_intrinsics is None:
                raise MogError(f"{folder}: frames without intrinsics (record them with record_frame)")
            warnings.warn(
                f"{folder}: frames recorded without intrinsics; using the scenario camera's "
                f"{tuple(round(v, 3) for v in fallback_intrinsics)}",
                stacklevel=2,
            )
        (k,) = found
        self.intrinsics = k or _intrinsics(fallback_intrinsics, "fallback")
        self._period = frame_period
        self.DeclareAbstractOutputPort(
            "camera.rgb_image",
            lambda: AbstractValue.Make(ImageRgba8U()),
            lambda c, o: o.set_value(self._frame(c)[0]),
        )
        self.DeclareAbstractOutputPort(
            "camera.depth_image",
            lambda: AbstractValue.Make(ImageDepth32F()),
            lambda c, o: o.set_value(self._frame(c)[1]),
        )

    def _frame(self, context):
        return self._frames[min(int(context.get_time() / self._period), len(self._frames) - 1)]


def record_frame(folder: str | Path, rgb: np.ndarray, depth: np.ndarray, intrinsics, index: int = 0) -> Path:
    """Writes frame_{index:04d}.npz: rgb, depth (m) and the intrinsics (fx, fy, cx, cy; pixel
    centres at integer coordinates) of the camera that took them, for `ReplayCamera`."""
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    path = folder / f"frame_{index:04d}.npz"
    np.savez_compressed(
        path,
        rgb=np.asarray(rgb)[:, :, :3],
        depth=np.asarray(depth, np.float32).reshape(np.asarray(rgb).shape[:2]),
        intrinsics=np.asarray(_intrinsics(intrinsics, "record_frame")),
    )
    return path


FRAME_TIMEOUT_MS = 2000  # a RealSense that sends no frameset for this long is lost


class _Images:
    """A grabbed (rgb, depth) pair held in abstract state. Drake copies abstract state on every
    unrestricted update, and its images cannot be deep-copied from Python (a tuple of them
    raised TypeError at the first grab); the pair is replaced, never changed, so copies share."""

    def __init__(self, rgb: ImageRgba8U, depth: ImageDepth32F):
        self.rgb, self.depth = rgb, depth

    def __copy__(self):
        return self

    def __deepcopy__(self, memo):
        return self


class RealSenseCamera(LeafSystem):
    """An Intel RealSense (pyrealsense2, the `hardware` extra): colour and depth aligned to
    colour, depth in metres. Its ``intrinsics`` are the colour stream's, read from the device
    (the frame depth is aligned to), and depth is scaled by the device's own depth scale. A
    new frame is grabbed at most every ``period`` seconds in a discrete update."""

    def __init__(self, width: int = 640, height: int = 480, fps: int = 30, period: float = 0.1):
        super().__init__()
        try:
            import pyrealsense2 as rs
        except ImportError:
            raise MogError(
                "the RealSense camera needs pyrealsense2: pip install 'mog_drake[hardware]'"
            ) from None
        self._rs = rs
        self._pipe = rs.pipeline()
        cfg = rs.config()
        cfg.enable_stream(rs.stream.color, width, height, rs.format.rgb8, fps)
        cfg.enable_stream(rs.stream.depth, width, height, rs.format.z16, fps)
        profile = self._pipe.start(cfg)
        self._scale = profile.get_device().first_depth_sensor().get_depth_scale()
        # rs2_intrinsics of the colour stream: fx, fy, ppx, ppy in pixels (pixel centres at
        # integer coordinates, as perception reads them), and a distortion model that
        # perception does not undo: a camera whose coefficients are not zero is flagged.
        k = profile.get_stream(rs.stream.color).as_video_stream_profile().get_intrinsics()
        if (k.width, k.height) != (width, height):
            self._pipe.stop()
            raise MogError(
                f"RealSense: colour stream is {k.width} x {k.height}, asked for {width} x {height}"
            )
        self.intrinsics = _intrinsics((k.fx, k.fy, k.ppx, k.ppy), "RealSense")
        if any(abs(c) > 1e-6 for c in k.coeffs):
            warnings.warn(
                f"RealSense: the colour stream has lens distortion {list(k.coeffs)}, which perception "
                "does not undo: expect position errors toward the image corners",
                stacklevel=2,
            )
        self._align = rs.align(rs.stream.color)
        self._images = self.DeclareAbstractState(
            AbstractValue.Make(_Images(ImageRgba8U(width, height), ImageDepth32F(width, height)))
        )
        self.DeclareAbstractOutputPort(
            "camera.rgb_image",
            lambda: AbstractValue.Make(ImageRgba8U()),
            lambda c, o: o.set_value(c.get_abstract_state(self._images).get_value().rgb),
        )
        self.DeclareAbstractOutputPort(
            "camera.depth_image",
            lambda: AbstractValue.Make(ImageDepth32F()),
            lambda c, o: o.set_value(c.get_abstract_state(self._images).get_value().depth),
        )
        self.DeclarePeriodicUnrestrictedUpdateEvent(period, 0.0, self._grab)

    def stop(self) -> None:
        """Stops the camera's stream (safe to call twice)."""
        try:
            self._pipe.stop()
        except RuntimeError:  # pyrealsense2: already stopped
            pass

    def _grab(self, context, state):
        try:
            frames = self._align.process(self._pipe.wait_for_frames(timeout_ms=FRAME_TIMEOUT_MS))
        except RuntimeError as e:  # librealsense: "Frame didn't arrive within ..."
            raise HardwareFault(f"camera: no frame within {FRAME_TIMEOUT_MS / 1000:g} s ({e})") from None
        rgb = np.asanyarray(frames.get_color_frame().get_data())
        depth = np.asanyarray(frames.get_depth_frame().get_data()).astype(np.float32) * self._scale
        depth[depth == 0] = np.nan
        state.get_mutable_abstract_state(self._images).set_value(_Images(_rgba(rgb), _depth(depth)))
