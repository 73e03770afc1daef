"""The device configuration (one TOML file, one table per component) and its loader."""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from ropecam.device.capture.config import CaptureConfig
from ropecam.device.pipeline.config import PipelineConfig
from ropecam.shared.config import check_range, load_tables
from ropecam.shared.errors import ConfigError
from ropecam.shared.protocol.auth import AuthConfig
from ropecam.shared.protocol.budget import MIN_BUDGET_BYTES
from ropecam.shared.protocol.wire import MAX_MESSAGE_BYTES
from ropecam.shared.transport.base import check_transport_url

__all__ = ["DaemonConfig", "DeviceConfig", "SenderConfig", "load_device_config"]


@dataclass(frozen=True, slots=True)
class SenderConfig:
    """Where results go and how.

    Parameters
    ----------
    sink
        Transport URL: ``udp://HOST:PORT`` or ``serial:///dev/ttyAMA0?baud=921600`` (``loop://NAME`` in tests).
    device_id
        This device's id in every message header (1..65534); the host shows one row per id.
    status_period_s
        Seconds between Status messages.
    queue_frames
        Results waiting to be encoded and sent; when the link cannot keep up the oldest is dropped (counted), so the
        pipeline never waits for the link.
    shape_tolerance_px
        Largest distance between a measured shape point and the shape the host decodes (the shape codec's
        tolerance, docs/protocol.md). 0.25 px keeps the mean frame of the simulated rigs and lab scenes <= 200 B
        (0.1 px: lab ~220-245 B, its curved, textured rope needs more control points); the decoded lab shapes are
        as close to the simulator's truth as the device's (docs/protocol.md, "The serial budget"). The tips are
        sent apart from the shapes, to 1/64 px, whatever the tolerance.
    frame_budget_bytes
        Most bytes one frame result may take on the link (COBS-framed, as on a serial line): a frame over it is sent
        with looser shapes (0.5, 1, 2 px) or without shapes and material points, and its quality record says so
        (``wire_tolerance_px``). 774: a 921600 baud line (8N1) at 119 FPS; 0: no budget (a network link).
    """

    sink: str = "udp://127.0.0.1:5600"
    device_id: int = 1
    status_period_s: float = 1.0
    queue_frames: int = 16
    shape_tolerance_px: float = 0.25
    frame_budget_bytes: int = 774

    def __post_init__(self) -> None:
        if not isinstance(self.sink, str) or "://" not in self.sink:
            raise ConfigError(
                f"sender.sink must be a transport URL (udp://HOST:PORT, serial:///dev/X), got {self.sink!r}"
            )
        try:
            check_transport_url(self.sink)  # scheme, host and port, device path, options: refused now, not at open
        except ConfigError as exc:
            raise ConfigError(f"sender.sink: {exc}") from exc
        check_range("sender.device_id", self.device_id, 1, 0xFFFE)
        check_range("sender.status_period_s", self.status_period_s, 0.05, 60.0)
        check_range("sender.queue_frames", self.queue_frames, 1, 10_000)
        check_range("sender.shape_tolerance_px", self.shape_tolerance_px, 0.02, 2.0)  # >= the 1/64 px quantum
        budget = self.frame_budget_bytes
        if (
            isinstance(budget, bool)
            or not isinstance(budget, int)
            or not (budget == 0 or MIN_BUDGET_BYTES <= budget <= MAX_MESSAGE_BYTES)
        ):
            raise ConfigError(
                f"sender.frame_budget_bytes must be 0 (no budget) or an integer in [{MIN_BUDGET_BYTES}, "
                f"{MAX_MESSAGE_BYTES}], got {budget!r}"
            )


@dataclass(frozen=True, slots=True)
class DaemonConfig:
    """Fault handling.

    Parameters
    ----------
    retry_initial_s, retry_max_s
        Backoff between attempts to reopen a lost camera or serial port (doubling up to the maximum).
    camera_give_up_s
        Exit with a non-zero code when the camera has been lost this long (systemd then restarts the service).
    """

    retry_initial_s: float = 0.5
    retry_max_s: float = 5.0
    camera_give_up_s: float = 60.0

    def __post_init__(self) -> None:
        check_range("daemon.retry_initial_s", self.retry_initial_s, 0.001, 60.0)
        check_range("daemon.retry_max_s", self.retry_max_s, self.retry_initial_s, 600.0)
        check_range("daemon.camera_give_up_s", self.camera_give_up_s, 0.0, 86_400.0)


@dataclass(frozen=True, slots=True)
class DeviceConfig:
    """Everything the daemon needs, one table per component."""

    capture: CaptureConfig = field(default_factory=CaptureConfig)
    pipeline: PipelineConfig = field(default_factory=PipelineConfig)
    sender: SenderConfig = field(default_factory=SenderConfig)
    control: AuthConfig = field(default_factory=AuthConfig)
    daemon: DaemonConfig = field(default_factory=DaemonConfig)


def load_device_config(path: str | Path | None, **overrides: dict[str, Any]) -> DeviceConfig:
    """Load ``device.toml`` (tables [capture], [pipeline], [sender], [control], [daemon]); None: all defaults.

    `overrides` maps a table name to values that replace the file's (e.g. command-line options; None is ignored).

    Raises
    ------
    ConfigError
        Missing or malformed file, unknown table or key, bad value (the message names file, table, key, value).
    """
    tables = {
        "capture": CaptureConfig,
        "pipeline": PipelineConfig,
        "sender": SenderConfig,
        "control": AuthConfig,
        "daemon": DaemonConfig,
    }
    return DeviceConfig(**load_tables(path, tables, **overrides))
