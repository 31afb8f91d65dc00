"""The camera's pose in the table frame from one RGB-D frame of a printed ChArUco board lying
flat at a known place on the table (OpenCV's aruco module: the `calibrate` extra).

The board (`BOARD`): 7 x 5 squares of 38 mm with 28 mm ArUco markers of the 4x4 dictionary,
266 x 190 mm, printed on A4 landscape at 100 %. Its frame B is OpenCV's: the origin at the
printed page's top-left square corner, x along the page's long side, y down the page, z into
the paper. Laid on the table with its long side along the table's x axis, the printed side up,
the page's top edge toward +y, and its centre at (x, y) with yaw (the `--board-at` values),
B's axes are the table's x, -y and -z.

`solve` finds the board's inner corners (sub-pixel), solves the camera's pose from them
(OpenCV's PnP, then Levenberg-Marquardt), and checks it against the depth image: the depth
each corner should have from that pose against the depth measured there. A frame is refused
(`MogError`, one line) where the board is not found, is not seen whole, the fit is poor, or
the depth disagrees (a board printed at another scale fits the image as well and the depth
does not).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from mog_drake.errors import MogError


@dataclass(frozen=True)
class BoardSpec:
    squares: tuple[int, int] = (7, 5)  # along the page's long side, across it
    square: float = 0.038  # m
    marker: float = 0.028  # m
    dictionary: str = "DICT_4X4_50"

    @property
    def size(self) -> tuple[float, float]:
        return (self.squares[0] * self.square, self.squares[1] * self.square)

    @property
    def corners(self) -> int:
        return (self.squares[0] - 1) * (self.squares[1] - 1)

    def text(self) -> str:
        w, h = self.size
        return (
            f"ChArUco {self.squares[0]} x {self.squares[1]} squares of {self.square * 1e3:.1f} mm, markers "
            f"{self.marker * 1e3:.1f} mm ({self.dictionary}): {w * 1e3:.0f} x {h * 1e3:.0f} mm. Print at 100 %; "
            f"the board is {w * 1e3:.0f} mm long: measure it."
        )


BOARD = BoardSpec()
PAPER = 0.0002  # m: the board's surface above the table (the sheet's thickness)
# A frame is refused below these: corners seen (of the board's), reprojection error (px RMS),
# and the board's corners against a board of its size (m RMS; a 95 % print: about 4 mm).
MIN_SEEN, MAX_REPROJECTION_PX, MAX_FIT = 0.75, 1.0, 0.001


def _aruco():
    try:
        import cv2
        from cv2 import aruco
    except ImportError:
        raise MogError("calibration needs OpenCV: pip install 'mog_drake[calibrate]'") from None
    return cv2, aruco


def _board(spec: BoardSpec = BOARD):
    cv2, aruco = _aruco()
    dictionary = aruco.getPredefinedDictionary(getattr(aruco, spec.dictionary))
    return aruco.CharucoBoard(spec.squares, spec.square, spec.marker, dictionary)


def board_image(spec: BoardSpec = BOARD, px_per_mm: float = 10.0) -> np.ndarray:
    """The board as a grey image (uint8), ``px_per_mm`` pixels per millimetre, no margin."""
    w, h = spec.size
    return _board(spec).generateImage((round(w * 1e3 * px_per_mm), round(h * 1e3 * px_per_mm)), marginSize=0)


def write_board(path, spec: BoardSpec = BOARD) -> str:
    """The board to print, at true scale on an A4 page (landscape), its size written under it:
    a .pdf or a .png (300 dpi)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    page = (297.0, 210.0)  # mm
    w, h = (v * 1e3 for v in spec.size)
    fig = plt.figure(figsize=(page[0] / 25.4, page[1] / 25.4))
    left, bottom = (page[0] - w) / 2 / page[0], (page[1] - h) / 2 / page[1] + 3.0 / page[1]
    ax = fig.add_axes((left, bottom, w / page[0], h / page[1]))
    ax.imshow(board_image(spec), cmap="gray", vmin=0, vmax=255, interpolation="nearest")
    ax.set_axis_off()
    fig.text(0.5, (bottom * page[1] - 6.0) / page[1], spec.text(), ha="center", va="top", fontsize=8)
    fig.savefig(path, dpi=300)
    plt.close(fig)
    return str(path)


def board_in_table(x: float, y: float, yaw: float, spec: BoardSpec = BOARD) -> np.ndarray:
    """X_TB (4x4): the board's frame (OpenCV's) in the table frame, the board's centre at
    (x, y) m on the table and turned by ``yaw`` rad (see the module's docstring)."""
    w, h = spec.size
    c, s = math.cos(yaw), math.sin(yaw)
    R_TP = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])  # the page, z up
    R_PB = np.diag([1.0, -1.0, -1.0])
    X = np.eye(4)
    X[:3, :3] = R_TP @ R_PB
    X[:3, 3] = [x, y, PAPER] + R_TP @ np.array([-w / 2, h / 2, 0.0])
    return X


@dataclass
class Calibration:
    X_TC: np.ndarray  # 4x4, the camera in the table frame
    corners: int  # seen
    reprojection_px: float  # RMS
    depth_residual: float  # m, RMS of the depth about the board's plane

    def rpy_deg(self) -> np.ndarray:
        """Roll, pitch, yaw (deg) of X_TC's rotation (Drake's RollPitchYaw: extrinsic x-y-z)."""
        R = self.X_TC[:3, :3]
        pitch = math.asin(-max(-1.0, min(1.0, R[2, 0])))
        roll = math.atan2(R[2, 1], R[2, 2])
        yaw = math.atan2(R[1, 0], R[0, 0])
        return np.degrees([roll, pitch, yaw])

    def yaml(self) -> str:
        """The pose as the scenario's camera.X_PB."""
        t = self.X_TC[:3, 3]
        r = self.rpy_deg()
        return (
            "camera:\n  X_PB:\n"
            f"    translation: [{t[0]:.5f}, {t[1]:.5f}, {t[2]:.5f}]\n"
            f"    rotation: !Rpy\n      deg: [{r[0]:.4f}, {r[1]:.4f}, {r[2]:.4f}]\n"
        )


def solve(
    rgb: np.ndarray, depth: np.ndarray, intrinsics, X_TB: np.ndarray, spec: BoardSpec = BOARD
) -> Calibration:
    """The camera's pose in the table frame from one RGB-D frame of the board at ``X_TB`` (see
    the module's docstring); ``intrinsics`` (fx, fy, cx, cy) of the colour image, pixel centres
    at integer coordinates; ``depth`` (m) aligned to it.

    The board's corners fix where it lies in the image and how it is turned; the depth on it
    fixes its plane. (Its corners alone tell a tilt from a shift poorly: 266 mm seen from
    0.8 m straight above, a camera turned by 0.1 deg moves them as one 1.4 mm to the side
    does, within a few tenths of a pixel: PnP on the rendered board went 20-30 mm and 2 deg
    wrong.) Each corner's ray meets the plane fitted to the depth inside the board; the board's
    known corners are then fitted to those points (Kabsch): their disagreement (RMS) says
    whether the board is the size it should be."""
    cv2, aruco = _aruco()
    board = _board(spec)
    grey = cv2.cvtColor(np.ascontiguousarray(np.asarray(rgb)[..., :3], np.uint8), cv2.COLOR_RGB2GRAY)
    found, ids, _, _ = aruco.CharucoDetector(board).detectBoard(grey)
    n = 0 if ids is None else len(ids)
    if n < 6:
        raise MogError("no calibration board found in the frame (" + spec.text().split(":")[0] + ")")
    if n < MIN_SEEN * spec.corners:
        raise MogError(
            f"only {n} of the board's {spec.corners} corners are seen: the whole board must be in view and sharp"
        )
    q = board.getChessboardCorners()[ids.ravel()].astype(np.float64)  # board frame, z = 0
    img = found.reshape(-1, 2).astype(np.float64)
    fx, fy, cx, cy = (float(v) for v in intrinsics)
    K = np.array([[fx, 0.0, cx], [0.0, fy, cy], [0.0, 0.0, 1.0]])
    normal, offset, plane_rms = _plane(np.asarray(depth, np.float64).reshape(grey.shape), img, K)
    rays = np.column_stack([(img[:, 0] - cx) / fx, (img[:, 1] - cy) / fy, np.ones(n)])
    p = rays * (offset / (rays @ normal))[:, None]  # the corners on the plane, camera frame
    R, t, fit_rms = _kabsch(q, p)
    if fit_rms > MAX_FIT:
        raise MogError(
            f"the board's corners lie {fit_rms * 1e3:.1f} mm (RMS) off a board of its size: is it printed at "
            f"100 % ({spec.size[0] * 1e3:.0f} mm long), and flat?"
        )
    proj = (q @ R.T + t) @ K.T
    rms = float(np.sqrt(np.mean(np.sum((proj[:, :2] / proj[:, 2:] - img) ** 2, axis=1))))
    if rms > MAX_REPROJECTION_PX:
        raise MogError(
            f"the fit is poor: the corners reproject {rms:.2f} px off (at most {MAX_REPROJECTION_PX:g}): a blurred "
            "or noisy frame?"
        )
    X_CB = np.eye(4)
    X_CB[:3, :3], X_CB[:3, 3] = R, t
    return Calibration(X_TB @ np.linalg.inv(X_CB), n, rms, plane_rms)


def _plane(depth: np.ndarray, corners: np.ndarray, K: np.ndarray) -> tuple[np.ndarray, float, float]:
    """(unit normal n toward the camera's side, offset d, RMS m) of the plane n . p = d (camera
    frame) fitted to the depth inside the corners' hull, twice (the second time without the
    points more than 3 RMS off the first); refused with too little depth there."""
    import cv2

    mask = np.zeros(depth.shape, np.uint8)
    cv2.fillConvexPoly(mask, cv2.convexHull(np.rint(corners).astype(np.int32)), 1)
    v, u = np.nonzero(mask.astype(bool) & np.isfinite(depth) & (depth > 0))
    if len(u) < 500:
        raise MogError("no depth on the board: the depth image has holes where the board lies")
    z = depth[v, u]
    pts = np.column_stack([(u - K[0, 2]) / K[0, 0] * z, (v - K[1, 2]) / K[1, 1] * z, z])
    keep = np.ones(len(pts), bool)
    for _ in range(2):
        c = pts[keep].mean(axis=0)
        normal = np.linalg.svd(pts[keep] - c, full_matrices=False)[2][2]
        normal = normal if normal[2] > 0 else -normal
        r = (pts - c) @ normal
        rms = float(np.sqrt(np.mean(r[keep] ** 2)))
        keep = np.abs(r) <= 3 * max(rms, 1e-6)
    return normal, float(c @ normal), rms


def _kabsch(q: np.ndarray, p: np.ndarray) -> tuple[np.ndarray, np.ndarray, float]:
    """(R, t, RMS) of the rigid motion taking points ``q`` onto ``p`` (N x 3 each), least
    squares (Kabsch)."""
    cq, cp = q.mean(axis=0), p.mean(axis=0)
    U, _, Vt = np.linalg.svd((q - cq).T @ (p - cp))
    D = np.diag([1.0, 1.0, np.sign(np.linalg.det(Vt.T @ U.T))])
    R = Vt.T @ D @ U.T
    t = cp - R @ cq
    return R, t, float(np.sqrt(np.mean(np.sum((q @ R.T + t - p) ** 2, axis=1))))


def pose_error(X_a: np.ndarray, X_b: np.ndarray) -> tuple[float, float]:
    """(m, deg) between two poses: their origins' distance and the angle of the rotation
    from one to the other."""
    dR = X_a[:3, :3].T @ X_b[:3, :3]
    angle = math.degrees(math.acos(max(-1.0, min(1.0, (np.trace(dR) - 1) / 2))))
    return float(np.linalg.norm(X_a[:3, 3] - X_b[:3, 3])), angle
