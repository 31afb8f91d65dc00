import pytest
from fakes.robotiq_server import FakeRobotiq

from mog_drake.hardware.robotiq import RobotiqCalibration, RobotiqClient, RobotiqError


def test_activate_move_status():
    with FakeRobotiq() as srv, RobotiqClient("127.0.0.1", srv.port, timeout=1.0) as g:
        g.activate()
        g.move(0.0, force=40.0, speed=0.15)
        s = g.status()
    assert srv.received[:5] == [
        "SET ACT 1",
        "SET POS 255",
        "SET SPE 255",
        f"SET FOR {round(255 * 20 / 215)}",
        "SET GTO 1",
    ]
    assert s["pos"] == 255 and s["width"] == 0.0 and s["object"] == 3 and not s["holding"]


def test_calibration_round_trip_and_force_range():
    c = RobotiqCalibration()
    assert c.width_to_pos(0.085) == 0 and c.width_to_pos(0.0) == 255
    assert c.pos_to_width(c.width_to_pos(0.04)) == pytest.approx(0.04, abs=c.stroke / 255)
    with pytest.raises(RobotiqError, match="outside"):
        c.force_to_byte(300.0)


def test_malformed_reply_is_an_error():
    with FakeRobotiq("malformed") as srv, RobotiqClient("127.0.0.1", srv.port, timeout=1.0) as g:
        with pytest.raises(RobotiqError, match="malformed reply 'POS banana' to 'GET POS'"):
            g.get("POS")


def test_slow_reply_times_out():
    with FakeRobotiq("slow", delay=0.6) as srv, RobotiqClient("127.0.0.1", srv.port, timeout=0.2) as g:
        with pytest.raises(RobotiqError, match="no reply to 'GET POS' within 0.2 s"):
            g.get("POS")


def test_dropped_connection_is_an_error():
    with FakeRobotiq("drop") as srv, RobotiqClient("127.0.0.1", srv.port, timeout=1.0) as g:
        with pytest.raises(RobotiqError, match="closed the connection|connection to the gripper lost"):
            g.activate()


def test_nobody_listening():
    import socket

    s = socket.socket()
    s.bind(("127.0.0.1", 0))
    port = s.getsockname()[1]
    s.close()
    with pytest.raises(RobotiqError, match="cannot reach the gripper"):
        RobotiqClient("127.0.0.1", port, timeout=0.5)
