"""A fake Robotiq 2F-85 URCap server on 127.0.0.1 speaking the real ASCII protocol.

Modelled on the 2F-85 instruction manual's registers as the URCap socket (TCP 63352) exposes
them: every ``SET`` is answered ``ack``, every ``GET X`` with ``X n``.

* Activation: ``SET ACT 1`` starts it; ``STA`` reads 1 (in progress) for ``activation_time``,
  then 3 (complete).
* A move: ``SET GTO 1`` copies the position request into ``PRE`` (the request echo) at once,
  ``OBJ`` reads 0 (moving) for ``move_time``, then 3 (at the target, no object) or, closing
  onto an object (``object_at`` set), 2 with ``POS`` where the fingers stopped.
* ``GTO 1`` before the activation completed moves nothing and raises fault 0x07 ("the
  activation bit must be set prior to action").

mode: "ok" behaves as above; "malformed" answers garbage to GET; "slow" waits ``delay`` before
each reply; "drop" closes the connection on the first request; "fault" reports ``FLT 14``
(0x0E, overcurrent) once a move starts; "ignore" acks a move's SET but acts on none of it (PRE, POS and
OBJ do not change); "stuck" starts a move that never ends (OBJ stays 0); "never_active"
never completes activation (as does a gripper constructed with a ``fault`` of 0x08 and up); "garbage" answers every request with an endless stream of bytes
and no newline.
"""

from __future__ import annotations

import socket
import threading
import time


class FakeRobotiq:
    def __init__(
        self,
        mode: str = "ok",
        delay: float = 0.0,
        activation_time: float = 0.15,
        move_time: float = 0.05,
        object_at: int | None = None,
        active: bool = False,
        fault: int = 0,
    ):
        self.mode, self.delay = mode, delay
        self.activation_time, self.move_time, self.object_at = activation_time, move_time, object_at
        self.vars = {"ACT": 0, "GTO": 0, "POS": 0, "PRE": 0, "SPE": 0, "FOR": 0, "OBJ": 3, "STA": 0, "FLT": 0}
        if active:
            self.vars.update(ACT=1, STA=3)
        # A fault already latched (FLT): a minor or major one (0x08 and up) keeps an
        # activation from completing until the fault is cleared (manual, gFLT).
        self.vars["FLT"] = fault
        self.request = 0  # the last SET POS
        self._act_at: float | None = None
        self._move: tuple[float, int] | None = None  # (started, target POS)
        self.received: list[str] = []
        self.received_at: list[float] = []  # time.monotonic() of each request, for tests
        self._lock = threading.Lock()
        self._srv = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
        self._srv.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        self._srv.bind(("127.0.0.1", 0))
        self._srv.listen(4)
        self._srv.settimeout(0.2)
        self.port = self._srv.getsockname()[1]
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._serve, daemon=True)
        self._thread.start()

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()

    def close(self):
        self._stop.set()
        self._thread.join(timeout=2)
        self._srv.close()

    def lose(self) -> None:
        """What the held object slipping out does (manual, OBJ: "fingers are at requested
        position"): the fingers, no longer blocked, finish the close to the request; OBJ 3."""
        with self._lock:
            self.vars["POS"], self.vars["OBJ"] = self.request, 3

    def _serve(self):
        while not self._stop.is_set():
            try:
                conn, _ = self._srv.accept()
            except TimeoutError:
                continue
            threading.Thread(target=self._client, args=(conn,), daemon=True).start()

    def _client(self, conn):
        conn.settimeout(0.2)
        buf = b""
        with conn:
            while not self._stop.is_set():
                try:
                    chunk = conn.recv(256)
                except TimeoutError:
                    continue
                except OSError:
                    return
                if not chunk:
                    return
                buf += chunk
                while b"\n" in buf:
                    line, buf = buf.split(b"\n", 1)
                    text = line.decode().strip()
                    self.received.append(text)
                    self.received_at.append(time.monotonic())
                    if self.mode == "drop":
                        return
                    if self.mode == "garbage":
                        self._stream_garbage(conn)
                        return
                    if self.mode == "slow":
                        time.sleep(self.delay)
                    try:
                        conn.sendall((self._answer(text) + "\n").encode())
                    except OSError:
                        return

    def _stream_garbage(self, conn):
        end = time.monotonic() + 5.0  # bounded: the client must give up long before
        while not self._stop.is_set() and time.monotonic() < end:
            try:
                conn.sendall(b"x" * 16)
            except OSError:
                return
            time.sleep(0.005)

    def _advance(self) -> None:
        """The gripper's own progress since the last request."""
        now = time.monotonic()
        v = self.vars
        if self._act_at is not None and self.mode != "never_active" and v["FLT"] < 0x08:
            v["STA"] = 3 if now - self._act_at >= self.activation_time else 1
        if self._move is not None and self.mode != "stuck":
            started, target = self._move
            if now - started >= self.move_time:
                closing = target > v["POS"]
                if self.object_at is not None and closing and target > self.object_at:
                    v["POS"], v["OBJ"] = self.object_at, 2
                else:
                    v["POS"], v["OBJ"] = target, 3
                self._move = None

    def _answer(self, text: str) -> str:
        parts = text.split()
        with self._lock:
            self._advance()
            v = self.vars
            # SET takes one or more "VAR value" pairs in one line, applied together, one "ack".
            if len(parts) >= 3 and len(parts) % 2 == 1 and parts[0] == "SET":
                pairs = list(zip(parts[1::2], parts[2::2]))
                if any(var not in v or not val.lstrip("-").isdigit() for var, val in pairs):
                    return "?"
                if not (self.mode == "ignore" and any(var == "GTO" for var, _ in pairs)):
                    for var, val in pairs:
                        self._set(var, int(val))
                return "ack"
            if len(parts) == 2 and parts[0] == "GET" and parts[1] in v:
                if self.mode == "malformed":
                    return "POS banana"
                return f"{parts[1]} {v[parts[1]]}"
            return "?"

    def _set(self, var: str, val: int) -> None:
        v = self.vars
        if var in ("PRE", "OBJ", "STA", "FLT"):
            return  # status registers are read-only
        if var == "POS":
            self.request = val  # the fingers' own POS changes only by moving
            return
        v[var] = val
        if var == "ACT":
            if val == 1 and v["STA"] != 3:
                self._act_at = time.monotonic()
                v["STA"] = 1
            elif val == 0:
                self._act_at, v["STA"] = None, 0
        if var == "GTO" and val == 1:
            if v["STA"] != 3:
                v["FLT"] = 0x07
                return
            v["PRE"], v["OBJ"] = self.request, 0
            self._move = (time.monotonic(), self.request)
            if self.mode == "fault":
                v["FLT"] = 0x0E
