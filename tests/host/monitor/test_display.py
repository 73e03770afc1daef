"""The monitor's displays and command line: rich table, plain lines, URLs, help."""

from __future__ import annotations

import io
import subprocess
import sys
import time

import pytest

from ropecam.host.cli import main
from ropecam.host.monitor.cli import listening_url, load_calibration
from ropecam.host.monitor.display import PlainDisplay, RichDisplay
from ropecam.host.receiver import check_packet
from ropecam.host.session import Session
from ropecam.shared.errors import ConfigError


@pytest.fixture
def busy_session(sim_device) -> Session:
    session = Session()
    messages = [data for _, data in sim_device.messages(12, start_t_ns=time.time_ns())]
    for data in messages[:5] + messages[7:]:  # two lost
        session.handle(check_packet(data, time.time_ns()))
    session.handle(check_packet(b"RC\x01junk-junk-junk-junk-junk", time.time_ns()))
    return session


def test_plain_display_prints_one_line_with_every_device(busy_session: Session) -> None:
    stream = io.StringIO()
    PlainDisplay(stream).update(busy_session, busy_session.snapshot(time.time_ns()))
    (line,) = stream.getvalue().splitlines()
    assert line.startswith("t=") and " cpu " in line
    assert "dev7" in line and "lost 2" in line and "LOSS +2" in line and "1 unreadable packets" in line


def test_rich_display_renders_a_row_per_device_with_warnings(busy_session: Session, monkeypatch) -> None:
    from rich.console import Console

    output = io.StringIO()
    display = RichDisplay("udp://:5600")
    display._live.stop()
    display._console = Console(file=output, force_terminal=True, width=220)
    display._live = type(display._live)(console=display._console, auto_refresh=False)
    display._live.start()
    display.update(busy_session, busy_session.snapshot(time.time_ns()))
    display.close()
    text = output.getvalue()
    assert "ropecam monitor: udp://:5600" in text and "LOSS +2" in text and "not recording" in text
    assert "simulated device 7 streaming" in text  # the device's Log line


@pytest.mark.parametrize(
    ("url", "expected"),
    [
        ("udp://0.0.0.0:5600", "udp://0.0.0.0:5600?listen=1"),
        ("udp://:5600", "udp://:5600?listen=1"),
        ("udp://10.0.0.2:5600?listen=0", "udp://10.0.0.2:5600?listen=0"),
        ("serial:///dev/ttyUSB0?baud=921600", "serial:///dev/ttyUSB0?baud=921600"),
    ],
)
def test_monitor_sources_always_receive(url: str, expected: str) -> None:
    assert listening_url(url) == expected


def test_calibration_options_need_the_plane(tmp_path) -> None:
    with pytest.raises(ConfigError, match="--camera needs --plane"):
        load_calibration("camera.yaml", None)
    assert load_calibration(None, None) == (None, {}, [])


def test_bad_arguments_give_clear_errors(tmp_path, capsys) -> None:
    assert main(["replay", str(tmp_path / "nothing.mcap")]) == 1  # missing data: a runtime error
    assert "does not exist" in capsys.readouterr().err
    (tmp_path / "exists.mcap").write_bytes(b"x")
    code = main(["monitor", "--source", "loop://", "--record", str(tmp_path / "exists.mcap"), "--duration-s", "0.1"])
    assert code == 2 and "exists" in capsys.readouterr().err
    assert main(["monitor", "--source", "tcp://x:1", "--duration-s", "0.1"]) == 2
    assert "unknown scheme" in capsys.readouterr().err


def test_help_is_fast_and_teaches() -> None:
    for command in ("monitor", "replay", "recover", "sim-device"):
        result = subprocess.run(
            [sys.executable, "-X", "importtime", "-m", "ropecam.host.cli", command, "--help"],
            capture_output=True,
            text=True,
            check=True,
        )
        assert "example" in result.stdout
        imported = result.stderr
        for heavy in ("mcap", "rich", "numba", "cv2"):
            assert f" {heavy}\n" not in imported and f" {heavy}." not in imported, f"{command} --help imports {heavy}"
