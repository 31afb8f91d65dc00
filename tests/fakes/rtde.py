"""A fake ur_rtde control + receive client: records calls, echoes the commanded joints."""

import numpy as np


class FakeRTDE:
    def __init__(self, q0, fail_after: int | None = None, protective_stop_after: int | None = None):
        self.q = np.asarray(q0, float).copy()
        self.calls: list[tuple] = []
        self.polls = 0
        self.fail_after = fail_after
        self.protective_stop_after = protective_stop_after

    # control interface
    def servoJ(self, q, speed, acceleration, time, lookahead_time, gain):
        self.calls.append(("servoJ", list(q)))
        self.q = np.asarray(q, float)
        return True

    def servoStop(self, a=10.0):
        self.calls.append(("servoStop",))
        return True

    # receive interface
    def getActualQ(self):
        self.polls += 1
        if self.fail_after is not None and self.polls > self.fail_after:
            raise RuntimeError("RTDE receive: socket closed")
        return list(self.q)

    def isProtectiveStopped(self):
        return self.protective_stop_after is not None and self.polls >= self.protective_stop_after
