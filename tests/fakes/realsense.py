"""A fake ``pyrealsense2`` module, modelled on what librealsense's Python binding does.

What each part models (librealsense's API reference: rs_pipeline.hpp, rs_frame.hpp,
rs_sensor.hpp, rs_processing.hpp, and its "API How To" page):

* ``pipeline().start(config)`` returns a ``pipeline_profile``; ``profile.get_stream(
  stream.color).as_video_stream_profile().get_intrinsics()`` returns ``rs2_intrinsics`` with
  ``width``, ``height``, ``ppx``, ``ppy``, ``fx``, ``fy`` (pixels; pixel centres at integer
  coordinates, as librealsense's own align and deproject use them), ``model`` and five
  ``coeffs`` (all zero on most D400 colour streams).
* ``profile.get_device().first_depth_sensor().get_depth_scale()`` is metres per z16 unit
  (0.001 by default on D400 cameras; other units can be set on the device).
* z16 depth is uint16; 0 means no depth at that pixel.
* ``align(stream.color).process(frameset)`` returns a frameset whose depth frame is resampled
  onto the colour stream's pixels (the fake's frames are already aligned).
* ``pipeline.wait_for_frames(timeout_ms)`` raises RuntimeError ("Frame didn't arrive within
  ...") when no frameset arrives in time.
"""

from __future__ import annotations

import types

import numpy as np


def module(
    rgb: np.ndarray,
    depth_m: np.ndarray,
    *,
    fx=615.0,
    fy=615.5,
    ppx=318.2,
    ppy=241.7,
    depth_scale=0.001,
    coeffs=(0.0, 0.0, 0.0, 0.0, 0.0),
    stream_size=None,
    frames=True,
):
    """A stand-in for ``import pyrealsense2``: a device streaming ``rgb`` (H, W, 3) and depth
    (H, W, metres; nan or 0 for none) quantised to z16 at ``depth_scale``."""
    h, w = rgb.shape[:2]
    sw, sh = stream_size or (w, h)
    z16 = np.where(np.isfinite(depth_m), np.round(np.nan_to_num(depth_m) / depth_scale), 0).astype(np.uint16)
    rs = types.SimpleNamespace()
    rs.stream = types.SimpleNamespace(color="color", depth="depth")
    rs.format = types.SimpleNamespace(rgb8="rgb8", z16="z16")
    rs.enabled = []

    intrinsics = types.SimpleNamespace(
        width=sw,
        height=sh,
        fx=fx,
        fy=fy,
        ppx=ppx,
        ppy=ppy,
        model="inverse_brown_conrady",
        coeffs=list(coeffs),
    )

    class _Frame:
        def __init__(self, data):
            self._data = data

        def get_data(self):
            return self._data

    class _Frameset:
        def get_color_frame(self):
            return _Frame(rgb.copy())

        def get_depth_frame(self):
            return _Frame(z16.copy())

    class config:
        def enable_stream(self, stream, width, height, fmt, fps):
            rs.enabled.append((stream, width, height, fmt, fps))

    class pipeline:
        def start(self, cfg):
            profile = types.SimpleNamespace()
            sensor = types.SimpleNamespace(get_depth_scale=lambda: depth_scale)
            device = types.SimpleNamespace(first_depth_sensor=lambda: sensor)
            profile.get_device = lambda: device
            video = types.SimpleNamespace(get_intrinsics=lambda: intrinsics)
            profile.get_stream = lambda s: types.SimpleNamespace(as_video_stream_profile=lambda: video)
            return profile

        def stop(self):
            rs.stopped = True

        def wait_for_frames(self, timeout_ms=5000):
            if not frames:
                raise RuntimeError(f"Frame didn't arrive within {timeout_ms}")
            return _Frameset()

    class align:
        def __init__(self, to):
            assert to == rs.stream.color

        def process(self, frameset):
            return frameset

    rs.config, rs.pipeline, rs.align = config, pipeline, align
    return rs
