"""Robotiq 2F-85 over the UR controller's URCap socket (TCP 63352, ASCII lines).

    SET ACT 1 / SET GTO 1 / SET POS n / SET SPE n / SET FOR n   -> "ack"
    GET POS / GET OBJ / GET STA                                  -> "POS n" / "OBJ n" / "STA n"

POS 0 is fully open (85 mm between the fingertips), 255 fully closed. OBJ: 0 moving,
1 stopped on an object while opening, 2 stopped on an object while closing, 3 reached the
target with no object.
"""

from __future__ import annotations

import socket
import time
from dataclasses import dataclass

from mog_drake.errors import MogError

DEFAULT_PORT = 63352


class RobotiqError(MogError):
    """The gripper refused, answered late, answered nonsense, or hung up."""


@dataclass
class RobotiqCalibration:
    stroke: float = 0.085  # m between the fingertips at POS 0
    force_min: float = 20.0  # N at FOR 0
    force_max: float = 235.0  # N at FOR 255
    speed_min: float = 0.020  # m/s at SPE 0
    speed_max: float = 0.150  # m/s at SPE 255

    def width_to_pos(self, width: float) -> int:
        return int(round(255 * (1 - min(max(width, 0.0), self.stroke) / self.stroke)))

    def pos_to_width(self, pos: int) -> float:
        return self.stroke * (1 - pos / 255)

    def force_to_byte(self, force: float) -> int:
        if not self.force_min <= force <= self.force_max:
            raise RobotiqError(
                f"grip force {force} N is outside the 2F-85's {self.force_min}-{self.force_max} N"
            )
        return int(round(255 * (force - self.force_min) / (self.force_max - self.force_min)))

    def speed_to_byte(self, speed: float) -> int:
        s = min(max(speed, self.speed_min), self.speed_max)
        return int(round(255 * (s - self.speed_min) / (self.speed_max - self.speed_min)))


class RobotiqClient:
    """A blocking client with a timeout on every reply."""

    def __init__(
        self,
        host: str,
        port: int = DEFAULT_PORT,
        timeout: float = 2.0,
        calibration: RobotiqCalibration | None = None,
    ):
        self.host, self.port, self.timeout = host, port, timeout
        self.cal = calibration or RobotiqCalibration()
        try:
            self._sock = socket.create_connection((host, port), timeout=timeout)
        except OSError as e:
            raise RobotiqError(f"cannot reach the gripper at {host}:{port}: {e.strerror or e}") from None
        self._sock.settimeout(timeout)
        self._buf = b""

    def close(self) -> None:
        try:
            self._sock.close()
        except OSError:
            pass

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()

    def _request(self, line: str) -> str:
        try:
            self._sock.sendall((line + "\n").encode())
            deadline = time.monotonic() + self.timeout
            while b"\n" not in self._buf:
                self._sock.settimeout(max(deadline - time.monotonic(), 1e-3))
                chunk = self._sock.recv(256)
                if not chunk:
                    raise RobotiqError(f"the gripper at {self.host}:{self.port} closed the connection")
                self._buf += chunk
        except TimeoutError:
            raise RobotiqError(f"no reply to '{line}' within {self.timeout:g} s") from None
        except OSError as e:
            raise RobotiqError(f"connection to the gripper lost: {e.strerror or e}") from None
        reply, self._buf = self._buf.split(b"\n", 1)
        return reply.decode(errors="replace").strip()

    def set(self, var: str, value: int) -> None:
        reply = self._request(f"SET {var} {int(value)}")
        if reply != "ack":
            raise RobotiqError(f"malformed reply {reply!r} to 'SET {var} {int(value)}' (expected 'ack')")

    def get(self, var: str) -> int:
        reply = self._request(f"GET {var}")
        parts = reply.split()
        if len(parts) != 2 or parts[0] != var or not parts[1].lstrip("-").isdigit():
            raise RobotiqError(f"malformed reply {reply!r} to 'GET {var}'")
        return int(parts[1])

    def activate(self) -> None:
        self.set("ACT", 1)

    def move(self, width: float, force: float, speed: float = 0.15) -> None:
        """Goes to a fingertip distance (m) with a force limit (N) and speed (m/s)."""
        self.set("POS", self.cal.width_to_pos(width))
        self.set("SPE", self.cal.speed_to_byte(speed))
        self.set("FOR", self.cal.force_to_byte(force))
        self.set("GTO", 1)

    def status(self) -> dict:
        pos = self.get("POS")
        obj = self.get("OBJ")
        return {
            "pos": pos,
            "width": self.cal.pos_to_width(pos),
            "object": obj,
            "holding": obj in (1, 2),
            "moving": obj == 0,
        }
