"""A fake Robotiq URCap server on 127.0.0.1 speaking the real ASCII protocol.

mode: "ok" answers like a gripper; "malformed" answers garbage to GET; "slow" waits longer than
the client's timeout; "drop" closes the connection on the first request.
"""

import socket
import threading
import time


class FakeRobotiq:
    def __init__(self, mode: str = "ok", delay: float = 0.0):
        self.mode, self.delay = mode, delay
        self.vars = {"ACT": 0, "GTO": 0, "POS": 0, "SPE": 0, "FOR": 0, "OBJ": 3, "STA": 0}
        self.received: list[str] = []
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
                    if self.mode == "drop":
                        return
                    if self.mode == "slow":
                        time.sleep(self.delay)
                    try:
                        conn.sendall((self._answer(text) + "\n").encode())
                    except OSError:
                        return

    def _answer(self, text: str) -> str:
        parts = text.split()
        if len(parts) == 3 and parts[0] == "SET" and parts[1] in self.vars:
            self.vars[parts[1]] = int(parts[2])
            if parts[1] == "GTO" and self.vars["GTO"] == 1:
                # Instant motion: closing on nothing reaches the target.
                self.vars["OBJ"] = 3
            return "ack"
        if len(parts) == 2 and parts[0] == "GET" and parts[1] in self.vars:
            if self.mode == "malformed":
                return "POS banana"
            return f"{parts[1]} {self.vars[parts[1]]}"
        return "?"
