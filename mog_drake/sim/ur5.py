"""The UR5 arm, written from its published Denavit-Hartenberg parameters.

`ur5_urdf()` generates `models/ur5.urdf` (run `python -m mog_drake.sim.ur5` to rewrite it).
Frames follow the standard DH chain: joint i rotates about z of frame i-1, then
T_i = Rz(q_i) Tz(d_i) Tx(a_i) Rx(alpha_i). The URDF places joint i+1 at Tz(d_i) Tx(a_i)
Rx(alpha_i) in link i, so its forward kinematics equal the DH product exactly (tested).
Collision geometry is capsules along the DH segments; masses are the published link masses.
"""

from __future__ import annotations

import math

import numpy as np
from pydrake.math import RigidTransform, RotationMatrix

from mog_drake.files import model_path

# UR5 DH parameters (m, rad).
DH_D = (0.089159, 0.0, 0.0, 0.10915, 0.09465, 0.0823)
DH_A = (0.0, -0.425, -0.39225, 0.0, 0.0, 0.0)
DH_ALPHA = (math.pi / 2, 0.0, 0.0, math.pi / 2, -math.pi / 2, 0.0)
LINK_MASSES = (3.7, 8.393, 2.275, 1.219, 1.219, 0.1879)  # kg, links 1..6
BASE_MASS = 4.0
JOINT_NAMES = ("shoulder_pan", "shoulder_lift", "elbow", "wrist_1", "wrist_2", "wrist_3")
JOINT_LIMIT = 2 * math.pi  # rad
VELOCITY_LIMIT = math.pi  # rad/s (180 deg/s)
EFFORT_LIMITS = (150.0, 150.0, 150.0, 28.0, 28.0, 28.0)  # N m
CAPSULE_RADII = (0.06, 0.054, 0.045, 0.04, 0.04, 0.035)

URDF_PATH = model_path("ur5.urdf")

# --- The robot's frames, the one place they are written ------------------------------------
#: The gripper's palm frame lies this far beyond the flange (tool0) along the tool axis (m): a
#: 2F-85 on its coupling. The palm's z points up, away from the fingers (the tool axis flipped),
#: its x along the closing axis; the fingertips are `finger_height` below it.
FLANGE_TO_PALM = 0.110


def base_transform(base_xyyaw) -> RigidTransform:
    """X_WB: the arm's base in the table (world) frame, from (x, y, yaw), on the table top."""
    bx, by, byaw = base_xyyaw
    return RigidTransform(RotationMatrix.MakeZRotation(byaw), [bx, by, 0.0])


def palm_in_flange() -> RigidTransform:
    """X_FP: the palm frame in the flange frame (tool0)."""
    return RigidTransform(RotationMatrix.MakeXRotation(np.pi), [0.0, 0.0, FLANGE_TO_PALM])


def dh_transform(q: float, d: float, a: float, alpha: float) -> np.ndarray:
    cq, sq, ca, sa = math.cos(q), math.sin(q), math.cos(alpha), math.sin(alpha)
    return np.array(
        [
            [cq, -sq * ca, sq * sa, a * cq],
            [sq, cq * ca, -cq * sa, a * sq],
            [0.0, sa, ca, d],
            [0.0, 0.0, 0.0, 1.0],
        ]
    )


def forward_kinematics(q) -> np.ndarray:
    """Pose (4x4) of the flange frame (tool0) in the base frame: the DH product."""
    T = np.eye(4)
    for i in range(6):
        T = T @ dh_transform(q[i], DH_D[i], DH_A[i], DH_ALPHA[i])
    return T


#: The UR5's DH frames 1..6, by the joint they carry.
LINK_FRAMES = ("shoulder", "elbow", "wrist 1", "wrist 2", "wrist 3", "flange")


class ArmFrames:
    """The arm's forward kinematics in the table frame, for checks and views: ``frames(q)``
    gives the origins of the shoulder, elbow, wrists, flange and palm, and the two
    fingertips (the plates' centres at ``finger_span``, ``finger_depth`` below the palm)."""

    def __init__(self, base_xyyaw, finger_depth: float = 0.040, finger_span: float = 0.085):
        self._base = base_transform(base_xyyaw).GetAsMatrix4()
        self._palm = palm_in_flange().GetAsMatrix4()
        h = finger_span / 2
        self._tips = np.array([[-h, 0.0, -finger_depth, 1.0], [h, 0.0, -finger_depth, 1.0]]).T

    def __call__(self, q) -> dict[str, np.ndarray]:
        T = self._base.copy()
        out = {}
        for i, name in enumerate(LINK_FRAMES):
            T = T @ dh_transform(q[i], DH_D[i], DH_A[i], DH_ALPHA[i])
            out[name] = T[:3, 3].copy()
        palm = T @ self._palm
        out["palm"] = palm[:3, 3]
        tips = (palm @ self._tips)[:3].T
        out["left fingertip"], out["right fingertip"] = tips[0], tips[1]
        return out


def _origin(xyz, rpy) -> str:
    return (
        f'<origin xyz="{xyz[0]:.6g} {xyz[1]:.6g} {xyz[2]:.6g}" rpy="{rpy[0]:.9g} {rpy[1]:.9g} {rpy[2]:.9g}"/>'
    )


def _capsule_segments(i: int) -> list[tuple[np.ndarray, np.ndarray]]:
    """Segments of link i (1-based) in its own frame: along z by d_i, then along x by a_i."""
    d, a = DH_D[i - 1], DH_A[i - 1]
    segs = []
    if abs(d) > 1e-9:
        segs.append((np.zeros(3), np.array([0.0, 0.0, d])))
    if abs(a) > 1e-9:
        segs.append((np.array([0.0, 0.0, d]), np.array([a, 0.0, d])))
    return segs


def _segment_geometry(p0: np.ndarray, p1: np.ndarray, r: float, name: str, color: str) -> str:
    mid = (p0 + p1) / 2
    v = p1 - p0
    length = float(np.linalg.norm(v))
    # Rotate z onto v: pitch about y, then yaw about z.
    pitch = math.atan2(math.hypot(v[0], v[1]), v[2])
    yaw = math.atan2(v[1], v[0])
    o = _origin(mid, (0.0, pitch, yaw))
    shape = f'<geometry><capsule radius="{r}" length="{length:.6g}"/></geometry>'
    return (
        f'    <visual name="{name}">{o}{shape}<material name="{color}"/></visual>\n'
        f'    <collision name="{name}">{o}{shape}</collision>\n'
    )


def _inertial(mass: float, com, r: float, length: float) -> str:
    # A solid cylinder about its own axis, approximating the link; good enough for a
    # position-controlled arm in simulation.
    ixx = mass * (3 * r * r + length * length) / 12
    izz = mass * r * r / 2
    return (
        f'    <inertial>{_origin(com, (0, 0, 0))}<mass value="{mass}"/>'
        f'<inertia ixx="{ixx:.6g}" iyy="{ixx:.6g}" izz="{izz:.6g}" ixy="0" ixz="0" iyz="0"/></inertial>\n'
    )


def ur5_urdf() -> str:
    out = [
        '<?xml version="1.0"?>\n',
        "<!-- Generated by mog_drake/sim/ur5.py from the UR5's published DH parameters. Do not edit. -->\n",
        '<robot name="ur5">\n',
        '  <material name="ur_grey"><color rgba="0.70 0.72 0.75 1"/></material>\n',
        '  <material name="ur_blue"><color rgba="0.25 0.45 0.70 1"/></material>\n',
        '  <link name="base_link">\n',
        _inertial(BASE_MASS, (0, 0, 0.03), 0.075, 0.06),
        '    <visual name="base">'
        + _origin((0, 0, 0.03), (0, 0, 0))
        + '<geometry><cylinder radius="0.075" length="0.06"/></geometry><material name="ur_grey"/></visual>\n',
        '    <collision name="base">'
        + _origin((0, 0, 0.03), (0, 0, 0))
        + '<geometry><cylinder radius="0.075" length="0.06"/></geometry></collision>\n',
        "  </link>\n",
    ]
    for i in range(1, 7):
        segs = _capsule_segments(i)
        length = sum(float(np.linalg.norm(b - a)) for a, b in segs) or 0.05
        com = np.mean([(a + b) / 2 for a, b in segs], axis=0) if segs else np.zeros(3)
        out.append(f'  <link name="link_{i}">\n')
        out.append(_inertial(LINK_MASSES[i - 1], com, CAPSULE_RADII[i - 1], length))
        for k, (a, b) in enumerate(segs):
            color = "ur_blue" if i in (1, 4, 5, 6) else "ur_grey"
            out.append(_segment_geometry(a, b, CAPSULE_RADII[i - 1], f"link_{i}_{k}", color))
        out.append("  </link>\n")
        parent = "base_link" if i == 1 else f"link_{i - 1}"
        if i == 1:
            o = _origin((0, 0, 0), (0, 0, 0))
        else:
            o = _origin((DH_A[i - 2], 0, DH_D[i - 2]), (DH_ALPHA[i - 2], 0, 0))
        out.append(
            f'  <joint name="{JOINT_NAMES[i - 1]}_joint" type="revolute">\n'
            f'    <parent link="{parent}"/><child link="link_{i}"/>\n    {o}\n    <axis xyz="0 0 1"/>\n'
            f'    <limit lower="{-JOINT_LIMIT:.9g}" upper="{JOINT_LIMIT:.9g}" velocity="{VELOCITY_LIMIT:.9g}" '
            f'effort="{EFFORT_LIMITS[i - 1]}"/>\n  </joint>\n'
        )
        out.append(
            f'  <transmission type="SimpleTransmission" name="{JOINT_NAMES[i - 1]}_trans">\n'
            f'    <actuator name="{JOINT_NAMES[i - 1]}_motor"/><joint name="{JOINT_NAMES[i - 1]}_joint"/>'
            "<mechanicalReduction>1</mechanicalReduction>\n  </transmission>\n"
        )
    out.append('  <link name="tool0"/>\n')
    out.append(
        '  <joint name="flange" type="fixed">\n    <parent link="link_6"/><child link="tool0"/>\n    '
        + _origin((DH_A[5], 0, DH_D[5]), (DH_ALPHA[5], 0, 0))
        + "\n  </joint>\n"
    )
    out.append("</robot>\n")
    return "".join(out)


if __name__ == "__main__":
    URDF_PATH.write_text(ur5_urdf())
    print(f"wrote {URDF_PATH}")
