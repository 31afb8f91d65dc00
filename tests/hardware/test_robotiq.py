import time

import pytest
from fakes.robotiq_server import FakeRobotiq

from mog_drake.errors import HardwareFault, MogError
from mog_drake.hardware.robotiq import RobotiqCalibration, RobotiqClient, RobotiqError


def test_activate_waits_for_sta_3_then_a_move_waits_for_its_end():
    with FakeRobotiq(activation_time=0.2) as srv, RobotiqClient("127.0.0.1", srv.port, timeout=1.0) as g:
        g.activate()
        assert srv.vars["STA"] == 3  # returned only once activation completed
        s = g.move(0.0, force=40.0, speed=0.15)
    assert srv.received[:2] == ["GET STA", "SET ACT 1"]
    assert srv.received.count("GET STA") >= 3  # polled: 1 (in progress) until 3
    i = srv.received.index(f"SET SPE 255 FOR {round(255 * 20 / 215)} POS 255 GTO 1")
    assert srv.received[i - 1] == "GET FLT"  # the fault register is read before the move
    assert srv.received[-1] == "GET FLT"  # and after it
    assert s["pos"] == 255 and s["width"] == 0.0 and s["object"] == 3 and not s["holding"]


def test_a_move_reports_an_object_detected():
    with FakeRobotiq(object_at=180, active=True) as srv, RobotiqClient("127.0.0.1", srv.port) as g:
        s = g.move(0.0, force=40.0)
    assert s["holding"] and s["object"] == 2 and s["pos"] == 180
    assert s["object_text"] == "stopped on an object while closing"


def test_calibration_round_trip_and_argument_ranges():
    c = RobotiqCalibration()
    assert c.width_to_pos(0.085) == 0 and c.width_to_pos(0.0) == 255
    assert c.pos_to_width(c.width_to_pos(0.04)) == pytest.approx(0.04, abs=c.stroke / 255)
    for bad in (lambda: c.force_to_byte(300.0), lambda: c.force_to_byte(float("nan"))):
        with pytest.raises(MogError, match="outside"):
            bad()
    with pytest.raises(MogError, match="outside"):
        c.width_to_pos(-0.01)
    with pytest.raises(MogError, match="positive"):
        c.speed_to_byte(float("inf"))


def test_bad_arguments_are_refused_before_anything_is_sent():
    with FakeRobotiq(active=True) as srv, RobotiqClient("127.0.0.1", srv.port, timeout=1.0) as g:
        with pytest.raises(MogError) as e:
            g.move(0.0, force=500.0)
        time.sleep(0.05)
        assert srv.received == []
    assert not isinstance(e.value, HardwareFault)  # a user error (exit 2), not the gripper's


@pytest.mark.parametrize(
    "mode,msg",
    [
        ("fault", r"gripper: fault 0x0E \(overcurrent\) during the move"),
        ("ignore", "gripper: the gripper did not take the command: PRE 0, expected 255"),
        ("stuck", r"gripper: still moving 0.3 s after the command \(OBJ 0\)"),
    ],
)
def test_a_move_that_fails_names_why(mode, msg):
    with FakeRobotiq(mode, active=True) as srv, RobotiqClient("127.0.0.1", srv.port, move_timeout=0.3) as g:
        with pytest.raises(RobotiqError, match=msg):
            g.move(0.0, force=40.0)


def test_a_fault_before_the_move_stops_it_unsent():
    with FakeRobotiq(active=True) as srv, RobotiqClient("127.0.0.1", srv.port) as g:
        srv.vars["FLT"] = 0x08
        with pytest.raises(
            RobotiqError, match=r"fault 0x08 \(maximum operating temperature exceeded\) before the move"
        ):
            g.move(0.0, force=40.0)
    assert not [r for r in srv.received if r.startswith("SET")]


def test_moving_before_activation_is_the_grippers_fault_0x07():
    with FakeRobotiq() as srv, RobotiqClient("127.0.0.1", srv.port, move_timeout=0.3) as g:
        with pytest.raises(RobotiqError, match="0x07"):
            g.move(0.0, force=40.0)


def test_activation_that_never_completes_times_out():
    with (
        FakeRobotiq("never_active") as srv,
        RobotiqClient("127.0.0.1", srv.port, activation_timeout=0.3) as g,
    ):
        with pytest.raises(
            RobotiqError, match=r"activation did not complete within 0.3 s \(STA 1, expected 3\)"
        ):
            g.activate()


def test_activating_a_faulted_gripper_names_the_fault_at_once():
    with (
        FakeRobotiq(fault=0x0E) as srv,
        RobotiqClient("127.0.0.1", srv.port, activation_timeout=5.0) as g,
    ):
        # The fault's own message, not the timeout's "did not complete within 5 s".
        with pytest.raises(RobotiqError, match=r"fault 0x0E \(overcurrent\) during activation \(STA 1\)"):
            g.activate()


def test_malformed_reply_is_an_error():
    with FakeRobotiq("malformed") as srv, RobotiqClient("127.0.0.1", srv.port, timeout=1.0) as g:
        with pytest.raises(RobotiqError, match="malformed reply 'POS banana' to 'GET POS'"):
            g.get("POS")


def test_slow_reply_times_out():
    with FakeRobotiq("slow", delay=0.6) as srv, RobotiqClient("127.0.0.1", srv.port, timeout=0.2) as g:
        with pytest.raises(RobotiqError, match="no reply to 'GET POS' within 0.2 s"):
            g.get("POS")


def test_a_peer_streaming_garbage_cannot_hold_the_client_past_its_deadline():
    # The peer streams for 5 s and then hangs up: a client without a deadline would end on
    # "closed the connection"; this one gives up on its byte cap (or its deadline) first.
    with FakeRobotiq("garbage") as srv, RobotiqClient("127.0.0.1", srv.port, timeout=0.3) as g:
        with pytest.raises(RobotiqError, match="garbage in reply to 'GET POS'|no reply to 'GET POS'"):
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


@pytest.mark.parametrize(
    "argv,words",
    [
        (["--port", "0"], "--port must be a TCP port"),
        (["--port", "70000"], "--port must be a TCP port"),
        (["--port", "-1"], "--port must be a TCP port"),
        (["--ip", " "], "--ip must name"),
        (["--ip", "gripper.invalid"], "gripper address 'gripper.invalid'"),
    ],
)
def test_gripper_arguments_that_name_no_gripper_are_user_errors(argv, words, capsys):
    """A bad port or address is the user's mistake (exit 2), not a gripper fault (exit 3)."""
    from mog_drake.cli import main

    args = ["gripper", "status", "--ip", "127.0.0.1", *argv]
    code = main(args)
    err = capsys.readouterr().err
    assert code == 2 and words in err and err.count("\n") == 1, err
