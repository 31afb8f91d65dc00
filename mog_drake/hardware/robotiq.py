"""Robotiq 2F-85 over the UR controller's URCap socket (TCP 63352, ASCII lines).

    SET VAR n [VAR n ...]   -> "ack"      (several registers in one line are applied together)
    GET VAR                 -> "VAR n"

Registers (the 2F-85 manual): ACT activate; GTO go to the requested position; POS the position
request when set, the fingers' position when read (0 open, 85 mm between the fingertips; 255
closed); SPE speed; FOR force; status: STA (3 = activation complete), PRE (echo of the
position request the gripper took), OBJ (0 moving, 1 stopped on an object while opening,
2 stopped on an object while closing, 3 at the requested position with no object), FLT (0 no
fault, else a fault code, `FAULTS`).

Every request has a hard deadline, whatever the peer sends; every argument is checked before
anything is sent; a move is one atomic SET and is confirmed by PRE; FLT is read before and
after each move. A device error raises `RobotiqError` (a `HardwareFault`); a bad argument
raises `MogError`.
"""

from __future__ import annotations

import math
import socket
import time
import warnings
from dataclasses import dataclass

import numpy as np
from pydrake.systems.framework import EventStatus, LeafSystem

from mog_drake.errors import HardwareFault, MogError
from mog_drake.geometry.gripper import OPEN_WIDTH
from mog_drake.hardware.safety import CommandLog, FaultLatch

DEFAULT_PORT = 63352
MAX_REPLY = 64  # bytes: the longest real reply is a few characters

# gFLT codes of the 2F-85 manual.
FAULTS = {
    0x05: "action delayed: the activation must complete first",
    0x07: "the activation bit must be set before any action",
    0x08: "maximum operating temperature exceeded",
    0x09: "no communication for at least 1 s",
    0x0A: "under the minimum operating voltage",
    0x0B: "automatic release in progress",
    0x0C: "internal fault",
    0x0D: "activation fault",
    0x0E: "overcurrent",
    0x0F: "automatic release completed",
}
OBJ_TEXT = {
    0: "moving",
    1: "stopped on an object while opening",
    2: "stopped on an object while closing",
    3: "at the requested position, no object",
}


def fault_text(code: int) -> str:
    return f"fault 0x{code:02X} ({FAULTS.get(code, 'unknown fault code')})"


def move_state(status: dict, pos: int, waited: float, timeout: float) -> tuple[bool, str]:
    """(done, problem) of a move to position request ``pos``, ``waited`` s after it was sent,
    from one `RobotiqClient.status`: done once the gripper took it (PRE) and stopped (OBJ
    non-zero); a problem is a fault code, or past ``timeout`` a command the gripper did not
    take or a move that does not end. The client's `wait` and the driver's poll both judge so."""
    if status["fault"]:
        return False, f"{fault_text(status['fault'])} during the move"
    if status["pre"] == pos and not status["moving"]:
        return True, ""
    if waited > timeout:
        if status["pre"] != pos:
            return False, f"the gripper did not take the command: PRE {status['pre']}, expected {pos}"
        return False, f"still moving {timeout:g} s after the command (OBJ 0)"
    return False, ""


class RobotiqError(HardwareFault):
    """The gripper reported a fault, refused or ignored a command, answered late or nonsense,
    or hung up. Messages start with ``gripper:``."""

    def __init__(self, message: str):
        super().__init__(message if message.startswith("gripper:") else f"gripper: {message}")


@dataclass
class RobotiqCalibration:
    stroke: float = 0.085  # m between the fingertips at POS 0
    force_min: float = 20.0  # N at FOR 0
    force_max: float = 235.0  # N at FOR 255
    speed_min: float = 0.020  # m/s at SPE 0
    speed_max: float = 0.150  # m/s at SPE 255

    def width_to_pos(self, width: float) -> int:
        if not (math.isfinite(width) and 0.0 <= width <= self.stroke + 1e-9):
            raise MogError(f"gripper width {width} m is outside the 2F-85's 0-{self.stroke} m")
        return int(round(255 * (1 - min(width, self.stroke) / self.stroke)))

    def pos_to_width(self, pos: int) -> float:
        return self.stroke * (1 - pos / 255)

    def force_to_byte(self, force: float) -> int:
        if not (math.isfinite(force) and self.force_min <= force <= self.force_max):
            raise MogError(f"grip force {force} N is outside the 2F-85's {self.force_min}-{self.force_max} N")
        return int(round(255 * (force - self.force_min) / (self.force_max - self.force_min)))

    def speed_to_byte(self, speed: float) -> int:
        if not (math.isfinite(speed) and speed > 0):
            raise MogError(f"gripper speed {speed} m/s must be a positive number")
        s = min(max(speed, self.speed_min), self.speed_max)
        return int(round(255 * (s - self.speed_min) / (self.speed_max - self.speed_min)))


class RobotiqClient:
    """A blocking client. ``timeout``: the hard deadline of one request (s);
    ``activation_timeout`` and ``move_timeout``: how long activation and a move may take."""

    POLL = 0.02  # s between status reads while waiting

    def __init__(
        self,
        host: str,
        port: int = DEFAULT_PORT,
        timeout: float = 2.0,
        calibration: RobotiqCalibration | None = None,
        activation_timeout: float = 5.0,
        move_timeout: float = 5.0,
    ):
        for name, v in (
            ("timeout", timeout),
            ("activation_timeout", activation_timeout),
            ("move_timeout", move_timeout),
        ):
            if not (math.isfinite(v) and v > 0):
                raise MogError(f"gripper {name} must be a positive number of seconds, got {v}")
        self.host, self.port, self.timeout = host, port, timeout
        self.activation_timeout, self.move_timeout = activation_timeout, move_timeout
        self.cal = calibration or RobotiqCalibration()
        try:
            self._sock = socket.create_connection((host, port), timeout=timeout)
        except socket.gaierror as e:  # the address itself is wrong: the user's, not the gripper's
            raise MogError(f"gripper address {host!r}: {e.strerror or e}") from None
        except OSError as e:
            raise RobotiqError(f"cannot reach the gripper at {host}:{port}: {e.strerror or e}") from None
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

    # --- one request, one line back, within the deadline ----------------------------------
    def _request(self, line: str) -> str:
        deadline = time.monotonic() + self.timeout
        try:
            self._sock.settimeout(self.timeout)
            self._sock.sendall((line + "\n").encode())
            while b"\n" not in self._buf:
                left = deadline - time.monotonic()
                if left <= 0:
                    raise TimeoutError
                if len(self._buf) > MAX_REPLY:
                    self._buf = b""
                    raise RobotiqError(
                        f"garbage in reply to '{line}': over {MAX_REPLY} bytes with no end of line"
                    )
                self._sock.settimeout(left)
                chunk = self._sock.recv(256)
                if not chunk:
                    raise RobotiqError(f"the gripper at {self.host}:{self.port} closed the connection")
                self._buf += chunk
        except TimeoutError:
            self._buf = b""
            raise RobotiqError(f"no reply to '{line}' within {self.timeout:g} s") from None
        except OSError as e:
            raise RobotiqError(f"connection to the gripper lost: {e.strerror or e}") from None
        reply, self._buf = self._buf.split(b"\n", 1)
        return reply.decode(errors="replace").strip()

    def set(self, *pairs: tuple[str, int]) -> None:
        """One atomic SET of one or more registers."""
        line = "SET " + " ".join(f"{var} {int(value)}" for var, value in pairs)
        reply = self._request(line)
        if reply != "ack":
            raise RobotiqError(f"malformed reply {reply!r} to '{line}' (expected 'ack')")

    def get(self, var: str) -> int:
        reply = self._request(f"GET {var}")
        parts = reply.split()
        if len(parts) != 2 or parts[0] != var or not parts[1].lstrip("-").isdigit():
            raise RobotiqError(f"malformed reply {reply!r} to 'GET {var}'")
        return int(parts[1])

    def check_fault(self, when: str) -> None:
        code = self.get("FLT")
        if code:
            raise RobotiqError(f"{fault_text(code)} {when}")

    # --- activation and moves ---------------------------------------------------------------
    def activate(self) -> None:
        """Activates the gripper (it opens and closes once to calibrate) and waits for STA 3."""
        if self.get("STA") == 3:
            self.check_fault("after activation")
            return
        self.set(("ACT", 1))
        deadline = time.monotonic() + self.activation_timeout
        while (sta := self.get("STA")) != 3:
            # A minor or major fault (0x08 and up; below are priority faults of commands)
            # stops the activation: said at once, not after the timeout.
            if (code := self.get("FLT")) >= 0x08:
                raise RobotiqError(f"{fault_text(code)} during activation (STA {sta})")
            if time.monotonic() > deadline:
                raise RobotiqError(
                    f"activation did not complete within {self.activation_timeout:g} s (STA {sta}, expected 3)"
                    + (f"; {fault_text(code)}" if code else "")
                )
            time.sleep(self.POLL)
        self.check_fault("after activation")

    def command(self, width: float, force: float, speed: float = 0.15) -> int:
        """Starts a move to a fingertip distance (m) with a force limit (N) and speed (m/s);
        returns the position request sent. Every argument is checked before anything is sent,
        and FLT before the move."""
        pos = self.cal.width_to_pos(width)
        spe = self.cal.speed_to_byte(speed)
        frc = self.cal.force_to_byte(force)
        self.check_fault("before the move")
        # Speed and force first, in the same line as the position and GTO: one atomic request.
        self.set(("SPE", spe), ("FOR", frc), ("POS", pos), ("GTO", 1))
        return pos

    def wait(self, pos: int) -> dict:
        """Waits for the move to ``pos`` to end: the request taken (PRE), then OBJ non-zero,
        then FLT read. Returns the status."""
        sent = time.monotonic()
        while True:
            s = self.status()
            done, problem = move_state(s, pos, time.monotonic() - sent, self.move_timeout)
            if problem:
                raise RobotiqError(problem)
            if done:
                break
            time.sleep(self.POLL)
        self.check_fault("after the move")
        return s

    def move(self, width: float, force: float, speed: float = 0.15) -> dict:
        """A move to its end: `command`, then `wait`."""
        return self.wait(self.command(width, force, speed))

    def status(self) -> dict:
        pos, obj, flt, pre = self.get("POS"), self.get("OBJ"), self.get("FLT"), self.get("PRE")
        return {
            "pos": pos,
            "width": self.cal.pos_to_width(pos),
            "object": obj,
            "object_text": OBJ_TEXT.get(obj, f"OBJ {obj}"),
            "holding": obj in (1, 2),
            "moving": obj == 0,
            "fault": flt,
            "pre": pre,
        }


def bench_check(
    ip: str, port: int, action: str, force: float, timeout: float, move_timeout: float
) -> tuple[dict, str]:
    """``action`` "open", "close" (after activating; each move waits for its end and says
    whether it stopped on an object) or "status" of the gripper at ``ip``:``port``; returns
    its status and a line saying it. Every argument is checked before anything is sent. A
    fault, an ignored command, a move that does not end or a peer that talks nonsense raises
    `HardwareFault`."""
    cal = RobotiqCalibration()
    try:
        cal.force_to_byte(force)
    except MogError as e:
        raise MogError(f"--force: {e}") from None
    with RobotiqClient(
        ip, port, timeout=timeout, calibration=cal, activation_timeout=move_timeout, move_timeout=move_timeout
    ) as g:
        if action in ("open", "close"):
            g.activate()
            status = g.move(cal.stroke if action == "open" else 0.0, force=force)
        else:
            status = g.status()
            g.check_fault("in the status read")
    return status, (
        f"gripper at {ip}:{port}: {action}: {status['object_text']}; "
        f"width {status['width'] * 1e3:.1f} mm (POS {status['pos']}, OBJ {status['object']}, no fault)"
    )


class RobotiqDriver(LeafSystem):
    """gripper.position (inner opening, m) -> moves; status -> gripper.state_measured.

    A changed width is sent as one move (`RobotiqClient.command`, which reads FLT first); each
    poll reads POS, OBJ, FLT and PRE. A fault code, a command the gripper did not take (PRE)
    or a move that does not end within ``move_timeout`` latches a fault. The deadline is the
    move's, not the command's: a new command sent before the move before it ended keeps that
    move's deadline, so a gripper that never ends a move faults however often it is told to
    move. After any fault the jaws never open again: whatever is held stays held.
    """

    def __init__(
        self,
        client,
        faults: FaultLatch,
        force: float,
        speed: float = 0.15,
        period: float = 0.05,
        dry_run: bool = False,
        *,
        log: CommandLog | None = None,
        initial_width: float = OPEN_WIDTH,
        move_timeout: float = 5.0,
        clock=time.monotonic,
    ):
        super().__init__()
        self._client, self._faults = client, faults
        self._force, self._speed, self._dry = force, speed, dry_run
        self._log = log or CommandLog()
        self._move_timeout, self._clock = move_timeout, clock
        self._cmd = self.DeclareVectorInputPort("gripper.position", 1)
        self._state = self.DeclareDiscreteState(np.array([initial_width, 0.0]))
        # The last command sent, and when the move under way began (None: no move under way).
        self._sent = {"width": None, "pos": None, "at": None}
        self._holding = False  # the last move ended on an object (OBJ 2) and none followed
        self.lost: list[float] = []  # when a held object was lost (simulated time, s)
        self.DeclareStateOutputPort("gripper.state_measured", self._state)
        self.DeclarePeriodicDiscreteUpdateEvent(period, 0.0, self._poll)
        self.DeclarePeriodicPublishEvent(period, 0.0, self._send)
        self._period = period

    def _fail(self, reason: str):
        self._faults.trip(reason if reason.startswith("gripper:") else f"gripper: {reason}")
        return EventStatus.Failed(None, self._faults.reason)

    def _poll(self, context, discrete_state):
        old = context.get_discrete_state(self._state).value()
        if self._dry:
            w = self._sent["width"] if self._sent["width"] is not None else old[0]
        else:
            try:
                s = self._client.status()
            except MogError as e:
                return self._fail(str(e))
            if s["fault"]:
                return self._fail(fault_text(s["fault"]))
            if self._sent["pos"] is not None and self._sent["at"] is not None:
                done, problem = move_state(
                    s, self._sent["pos"], self._clock() - self._sent["at"], self._move_timeout
                )
                if problem:
                    return self._fail(problem)
                if done:
                    self._sent["at"] = None  # the next command begins a new move
                    self._holding = s["object"] == 2
            if self._holding and self._sent["at"] is None and s["object"] == 3:
                self._holding = False
                self.lost.append(context.get_time())
                warnings.warn(
                    f"gripper: lost what it held at t={context.get_time():.2f} s (OBJ 2 -> 3: the"
                    " fingers closed to the requested width); counted as a drop",
                    stacklevel=1,
                )
            w = s["width"]
        discrete_state.get_mutable_vector(self._state).SetFromVector([w, (w - old[0]) / self._period])
        return EventStatus.Succeeded()

    def _send(self, context):
        w = float(self._cmd.Eval(context)[0])
        if self._sent["width"] is not None and abs(w - self._sent["width"]) < 1e-3:
            return EventStatus.Succeeded()
        if self._faults and (self._sent["width"] is None or w > self._sent["width"]):
            # After a fault the jaws never open: whatever is held stays held.
            return EventStatus.Succeeded()
        if self._dry:
            self._log.write("robotiq", context.get_time(), width=round(w, 4), force=self._force)
        else:
            try:
                pos = self._client.command(w, self._force, self._speed)
            except MogError as e:
                return self._fail(str(e))
            self._sent.update(pos=pos, at=self._sent["at"] if self._sent["at"] is not None else self._clock())
            self._holding = False
        self._sent["width"] = w
        return EventStatus.Succeeded()
