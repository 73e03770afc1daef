"""The daemon's main loop: camera -> pipeline -> sender, with control between frames, Status every period,
and recovery from a lost camera or link.

Threads: the main loop (capture and pipeline; the Numba kernels release the GIL), the sender (encoding and
sending) and the control listener (receiving). Only the main loop touches the camera and the pipeline.
"""

from __future__ import annotations

import dataclasses
import logging
import threading
import time
from collections import Counter
from collections.abc import Callable

from ropecam.device.capture.driver import DriverFactory
from ropecam.device.capture.source import CameraSource, CaptureCounters, CapturedFrame, ControlUnsupportedError
from ropecam.device.daemon.config import DeviceConfig
from ropecam.device.daemon.control import ControlListener, PendingCommand
from ropecam.device.daemon.health import CpuLoadMeter, RateMeter, read_temperature_c
from ropecam.device.daemon.systemd import Notifier
from ropecam.device.pipeline.pipeline import Pipeline
from ropecam.device.pipeline.result import FrameStatus, PipelineResult, to_wire
from ropecam.device.senders.stream import ResultSender
from ropecam.shared.config import check_readout
from ropecam.shared.errors import CaptureError, ConfigError, TransportError
from ropecam.shared.plane import read_plane_file
from ropecam.shared.protocol import AckResult, Command, ControlAck, Log, Status, Verifier, load_key, split_frame
from ropecam.shared.protocol.shapes import ShapeCodecConfig
from ropecam.shared.transport.base import Transport, open_transport

__all__ = ["EXIT_CAMERA_LOST", "EXIT_OK", "Daemon"]

_log = logging.getLogger(__name__)
EXIT_OK = 0
EXIT_CAMERA_LOST = 3
_BROKEN_LINK_DRAIN_S = 0.2  # a broken link cannot take the backlog: do not wait long for it


class Daemon:
    """Run the rig: measure every frame and stream the results until stopped.

    Parameters
    ----------
    config
        The device configuration.
    notifier
        systemd notifications (default: none).
    driver_factory
        Replaces the V4L2 driver layer (tests).
    transport_factory
        Opens the link from the sink URL (default `open_transport`).
    """

    def __init__(
        self,
        config: DeviceConfig,
        notifier: Notifier | None = None,
        driver_factory: DriverFactory | None = None,
        transport_factory: Callable[[str], Transport] = open_transport,
    ) -> None:
        self.config = config
        self.notifier = notifier or Notifier()
        self._driver_factory = driver_factory
        self._transport_factory = transport_factory
        self._verifier = Verifier(load_key(config.control))
        self.statuses: Counter[str] = Counter()
        self.check_failures: Counter[str] = Counter()
        """Frames a self-check failed, by reason (``"length"``, ``"no_blur"``, ...; sent as ``check_<reason>``)."""
        self.frames_measured = 0
        self.frames_paused = 0
        """Frames delivered while measuring was stopped by a STOP command (captured, not measured)."""
        self.capture = CaptureCounters()
        """The camera's counts since the daemon started (every source it opened), final when `run` returns."""
        self.link_reopened = 0
        self.camera_reopened = 0
        self._pipeline_config = config.pipeline
        plane_file = config.pipeline.plane_file
        self._plane = None if plane_file is None else read_plane_file(plane_file)  # [pipeline] plane_file
        self._pipeline: Pipeline | None = None
        self._result = PipelineResult(0, 0, 0, FrameStatus.BAD_FRAME)  # refilled by every frame (`_measure`)
        self._running = True
        self._raw_frame_requested = False
        self._camera_lost_since: float | None = None
        self._started = time.monotonic_ns()
        self._cpu = CpuLoadMeter()
        self._rate = RateMeter()
        # Camera settings changed by control, re-applied whenever the camera is reopened (the config has the rest).
        self.camera_settings: dict[str, int] = {}
        # Counts of the sources replaced after a camera loss, so the totals in Status never go backwards.
        self._previous_sources = CaptureCounters()
        self.control_results: Counter[str] = Counter()  # by AckResult name, and REFUSED (forged, replayed)
        self._endpoint_counted = (0, 0)
        self._previous_links: Counter[str] = Counter()
        self._link_open = False
        self._next_sequence = 0  # of the next link's first message
        self._next_ping = 0.0
        self._ready = False  # READY sent to systemd
        self.transport: Transport | None = None
        self.sender: ResultSender | None = None
        self.listener: ControlListener | None = None

    # -- link ----------------------------------------------------------------------------------------------------
    def _open_link(self, stop: threading.Event) -> bool:
        """Open the transport, sender and control listener, retrying with backoff; False if stopped first."""
        delay = self.config.daemon.retry_initial_s
        sequence = self._next_sequence
        while not stop.is_set():
            try:
                self.transport = self._transport_factory(self.config.sender.sink)
            except TransportError as exc:
                _log.error("cannot open the link %s: %s (retrying in %.1f s)", self.config.sender.sink, exc, delay)
                self.notifier.status(f"link {self.config.sender.sink} unavailable: {exc}")
                self._wait(stop, delay)
                delay = min(delay * 2, self.config.daemon.retry_max_s)
                continue
            sender_config = self.config.sender
            broken = threading.Event()
            self.sender = ResultSender(
                self.transport, sender_config.device_id, sender_config.queue_frames, sequence, link_broken=broken,
                shape_config=ShapeCodecConfig(tolerance_px=sender_config.shape_tolerance_px),
                frame_budget_bytes=sender_config.frame_budget_bytes,
            )  # fmt: skip
            self.listener = ControlListener(
                self.transport,
                self.sender,
                sender_config.device_id,
                self._verifier,
                self._pipeline_config.rope_length_m,
                link_broken=broken,
            )
            self._link_open = True
            return True
        return False

    def _count_endpoint(self) -> None:
        """Move the listener's counts (refused, invalid at arrival) into the daemon's running totals."""
        if self._link_open and self.listener is not None:
            stats = self.listener.endpoint.stats
            self.control_results["REFUSED"] += stats.refused - self._endpoint_counted[0]
            self.control_results["INVALID"] += stats.failed - self._endpoint_counted[1]
            self._endpoint_counted = (stats.refused, stats.failed)

    def _link_counts(self) -> Counter[str]:
        """Link counters since the daemon started: the closed links' plus the current one's."""
        totals = self._previous_links.copy()
        if not self._link_open:
            return totals
        if self.sender is not None:
            stats = self.sender.stats
            totals.update(
                queue_dropped=stats.dropped_queue_full,
                encode_errors=stats.encode_errors,
                link_errors=stats.link_errors,
                closed_dropped=stats.dropped_closed,
                budget_cuts=stats.budget_cuts,
            )
        if self.transport is not None:
            totals.update(messages_dropped=self.transport.stats.send_dropped)
        return totals

    def _close_link(self) -> None:
        if not self._link_open:
            return
        self._count_endpoint()
        self._endpoint_counted = (0, 0)
        if self.sender is not None:
            self.sender.close(_BROKEN_LINK_DRAIN_S if self._link_broken() else 2.0)
            self._next_sequence = self.sender.next_sequence
        self._previous_links = self._link_counts()
        if self.listener is not None:
            self.listener.close()
        if self.transport is not None:
            self.transport.close()
        self._link_open = False  # the objects stay for a look at their stats; their counts are in the totals now

    def _link_broken(self) -> bool:
        """True when the transport closed, or the sender or the listener found it failing."""
        if not self._link_open or self.transport is None or self.transport.closed:
            return True
        return self.sender is not None and self.sender.link_broken.is_set()

    def _reopen_link(self, stop: threading.Event) -> None:
        _log.warning("the link %s is broken; reopening", self.config.sender.sink)
        waiting = self.listener.commands if self.listener is not None else None
        self._close_link()
        if self._open_link(stop):
            self.link_reopened += 1
            while waiting is not None and not waiting.empty() and self.listener is not None:
                self.listener.commands.put(waiting.get())  # verified before the link broke: apply and ack them
            self._send_log(f"link {self.config.sender.sink} reopened")

    # -- watchdog ------------------------------------------------------------------------------------------------
    def _ping(self) -> None:
        """Ping systemd's watchdog when a ping is due (from READY on: start-up is under TimeoutStartSec)."""
        period_s = self.notifier.watchdog_period_s
        now = time.monotonic()
        if self._ready and period_s is not None and now >= self._next_ping:
            self.notifier.watchdog()
            self._next_ping = now + period_s

    def _wait(self, stop: threading.Event, seconds: float) -> None:
        """Wait `seconds` (or until stopped) in slices no longer than the watchdog period, pinging it."""
        end = time.monotonic() + seconds
        slice_s = self.notifier.watchdog_period_s or seconds
        while not stop.is_set():
            self._ping()
            left = end - time.monotonic()
            if left <= 0:
                return
            stop.wait(min(left, slice_s))

    # -- camera --------------------------------------------------------------------------------------------------
    def _open_camera(self, stop: threading.Event) -> CameraSource | None:
        """Open and start the camera, retrying with backoff; None when stopped or lost longer than allowed."""
        delay = self.config.daemon.retry_initial_s
        while not stop.is_set():
            source = None
            self._ping()
            try:
                source = self.config.capture.open(self._driver_factory)
                source.start()
                # The readout time against the camera's real frame period (the config may not give the rate).
                check_readout("capture.readout_us", self.config.capture.readout_us, source.fps)
                if self._warm_up(source):
                    # Frames that streamed in while the pipeline was built are not part of the measurement: start
                    # the stream again (this also zeroes the source's counters), so the first frame is not skipped.
                    source.stop()
                    source.start()
                self._camera_lost_since = None
                self._reapply_settings(source)
                return source
            except ConfigError:
                # Settings that do not fit this camera (a plane or mask of another size, a readout time longer
                # than its frame period): no retry helps; the caller ends the daemon.
                if source is not None:
                    source.stop()
                raise
            except CaptureError as exc:
                if source is not None:
                    source.stop()
                now = time.monotonic()
                self._camera_lost_since = self._camera_lost_since or now
                lost_s = now - self._camera_lost_since
                _log.error("camera unavailable for %.1f s: %s", lost_s, exc)
                self._send_log(f"camera unavailable for {lost_s:.1f} s: {exc}")
                self.notifier.status(f"camera unavailable: {exc}")
                if lost_s >= self.config.daemon.camera_give_up_s:
                    return None
                self._send_status(None)
                self._wait(stop, delay)
                delay = min(delay * 2, self.config.daemon.retry_max_s)
        return None

    def _warm_up(self, source: CameraSource) -> bool:
        """Build the pipeline for the camera's image size and run one blank frame through it (buffers allocated,
        every kernel called once), so that the first camera frame is measured at full speed; True if it built one.
        """
        width, height = source.image_size
        if self._pipeline is not None and self._pipeline.shape == (height, width):
            return False
        self._pipeline = self._new_pipeline((width, height))
        self._pipeline.warm_up()  # a blank frame (no rope: no tracking state) and the edge model's tables
        return True

    def _new_pipeline(self, image_size: tuple[int, int]) -> Pipeline:
        """A pipeline for frames of `image_size` with the camera's readout time and the plane calibration."""
        return Pipeline(self._pipeline_config, image_size, self.config.capture.readout_us, self._plane)

    # -- commands --------------------------------------------------------------------------------------------------
    def _apply(self, pending: PendingCommand, source: CameraSource) -> ControlAck:
        """Apply one command between frames and return its acknowledgement (what really happened)."""
        command, values = pending.control.command, pending.control.values
        result, detail = AckResult.APPLIED, ""
        try:
            if command is Command.SET_EXPOSURE:
                got = source.set_exposure_us(round(values[0]))
                self.camera_settings["exposure_us"] = round(values[0])
                detail = f"exposure {got} us"
            elif command is Command.SET_GAIN:
                got = source.set_gain(round(values[0]))
                self.camera_settings["gain"] = round(values[0])
                detail = f"gain {got} (camera units)"
            elif command is Command.SET_THRESHOLDS:
                self._rebuild(source, canny_low=values[0], canny_high=values[1])
            elif command is Command.SET_MATERIAL_POINTS:
                self._rebuild(source, material_points_m=tuple(values))
            elif command is Command.RESET_ROI:
                if self._pipeline is not None:
                    self._pipeline.reset_tracking()
            elif command is Command.START:
                self._running = True
            elif command is Command.STOP:
                self._running = False
            elif command is Command.REQUEST_RAW_FRAME:
                self._raw_frame_requested = True
            else:
                result, detail = AckResult.UNSUPPORTED, "the device does not know this command"
        except ControlUnsupportedError as exc:
            result, detail = AckResult.UNSUPPORTED, str(exc)
        except ValueError as exc:  # the camera refuses the value (its range, the frame period)
            result, detail = AckResult.INVALID, str(exc)
        except CaptureError as exc:  # the camera failed while setting it (and is probably lost)
            result, detail = AckResult.FAILED, str(exc)
        self.control_results[result.name] += 1  # INVALID at arrival and REFUSED: see _count_endpoint
        if result is AckResult.APPLIED:
            _log.info("applied %s %s", command.name, list(values))
        else:
            _log.warning("could not apply %s %s: %s: %s", command.name, list(values), result.name, detail)
        return ControlAck(pending.acked_sequence, command, result, detail[:200])

    def _apply_pending(self, source: CameraSource) -> None:
        while self.listener is not None and not self.listener.commands.empty():
            ack = self._apply(self.listener.commands.get(), source)
            if self.sender is not None:
                self.sender.submit(ack)

    def _reapply_settings(self, source: CameraSource) -> None:
        """Put back the exposure and gain set by control on a reopened camera (the config has the originals)."""
        setters = {"exposure_us": source.set_exposure_us, "gain": source.set_gain}
        for name, value in self.camera_settings.items():
            try:
                setters[name](value)
            except ValueError as exc:
                _log.warning("could not re-apply %s = %s on the reopened camera: %s", name, value, exc)
                self._send_log(f"could not re-apply {name} = {value}: {exc}")

    def _rebuild(self, source: CameraSource, **changes: object) -> None:
        """New pipeline settings: build and warm the new pipeline now, between frames, so that the next frame is
        measured at full speed (what it learnt of the rope, such as the fixed end and the width, is learnt again)."""
        self._pipeline_config = dataclasses.replace(self._pipeline_config, **changes)
        self._pipeline = None
        self._warm_up(source)

    # -- reporting -----------------------------------------------------------------------------------------------
    def _send_log(self, text: str, level: int = logging.WARNING) -> None:
        if self.sender is not None:
            self.sender.submit(Log(level=level, text=text[:1000]))

    def _send_status(self, source: CameraSource | None) -> None:
        if self.sender is None:
            return
        counters = self._capture_totals(source)
        delivered = counters.delivered
        link = self._link_counts()
        self._count_endpoint()
        applied = self.control_results["APPLIED"]
        named = {
            "camera_lost": int(self._camera_lost_since is not None),
            "capture_timeouts": counters.timeouts,
            "capture_skipped": counters.skipped,
            "queue_dropped": link["queue_dropped"],
            "encode_errors": link["encode_errors"],
            "link_errors": link["link_errors"],
            "closed_dropped": link["closed_dropped"],
            "budget_cuts": link["budget_cuts"],
            "link_reopened": self.link_reopened,
            "camera_reopened": self.camera_reopened,
            "control_applied": applied,
            "control_failed": sum(self.control_results.values()) - applied - self.control_results["REFUSED"],
            "control_refused": self.control_results["REFUSED"],
            "running": int(self._running),
        }
        named.update({f"frames_{status.lower()}": count for status, count in self.statuses.items()})
        named.update({f"check_{reason}": count for reason, count in self.check_failures.items()})
        status = Status(
            frame_rate_hz=self._rate.sample(delivered),
            frames_captured=delivered,
            frames_dropped=counters.dropped + counters.skipped + link["queue_dropped"],
            messages_dropped=link["messages_dropped"],
            exposure_us=int(source.exposure_us) if source is not None else 0,
            gain=float(self.camera_settings.get("gain", 0)),  # camera units: see docs/daemon.md
            uptime_ns=time.monotonic_ns() - self._started,
            cpu_load=self._cpu.sample(),
            temperature_c=read_temperature_c(),
            counters=tuple((name[:32], int(value)) for name, value in named.items()),
        )
        self.sender.submit(status)

    def _capture_totals(self, source: CameraSource | None) -> CaptureCounters:
        """Capture counters since the daemon started: the replaced sources' plus the current one's."""
        totals = dataclasses.replace(self._previous_sources)
        if source is not None:
            for name, value in source.counters.as_dict().items():
                setattr(totals, name, getattr(totals, name) + value)
        return totals

    def _retire(self, source: CameraSource) -> None:
        """Stop a lost source and keep its counts in the running totals."""
        source.stop()
        self._previous_sources = self._capture_totals(source)

    def accounting(self) -> dict[str, int]:
        """Return where every frame of the camera went since the daemon started (final when `run` returned).

        ``frames`` (the span of the camera's sequence numbers seen) is ``measured + paused + skipped + dropped``:
        measured by the pipeline (by status in `statuses`), delivered while stopped by control (``paused``),
        overtaken by a newer frame while the pipeline was still busy (``skipped``: the pipeline was late), or never
        delivered (``dropped``: gaps in the driver's sequence numbers, frames missing from a recording).
        """
        capture = self.capture
        counts = {
            "measured": self.frames_measured,
            "paused": self.frames_paused,
            "skipped": capture.skipped,
            "dropped": capture.dropped,
        }
        return {"frames": sum(counts.values()), **counts, "timeouts": capture.timeouts}

    def summary(self, code: int) -> str:
        """Return the closing line: where every frame went (`accounting`), the statuses and the exit code."""
        counts = self.accounting()
        statuses = ", ".join(f"{k} {v}" for k, v in sorted(self.statuses.items())) or "none"
        lost = [
            f"skipped {counts['skipped']} (the pipeline was late: a newer frame overtook them)",
            f"dropped {counts['dropped']} (never delivered: driver or recording gaps)",
        ]
        if counts["paused"]:
            lost.append(f"{counts['paused']} not measured (stopped by control)")
        return (
            f"measured {counts['measured']} of {counts['frames']} frames ({statuses}); {', '.join(lost)}; exit {code}"
        )

    # -- the loop ----------------------------------------------------------------------------------------------------
    def _measure(self, frame: CapturedFrame, source: CameraSource) -> None:
        if self._pipeline is None:
            self._pipeline = self._new_pipeline(source.image_size)
        # One record refilled every frame: it is counted and turned into the wire record before the next one.
        result = self._pipeline.process(frame.image, frame.sequence, frame.t_ns, frame.exposure_us, out=self._result)
        self.statuses[result.status.name] += 1
        if result.reason:
            self.check_failures[result.reason] += 1
        self.frames_measured += 1
        if self.sender is not None:
            self.sender.submit_frame(to_wire(result))

    def run(self, stop: threading.Event) -> int:
        """Run until `stop` is set, a recording ends, or the camera stays lost too long; return the exit code."""
        if not self._open_link(stop):
            return EXIT_OK
        try:
            source = self._open_camera(stop)
        except BaseException:
            self._close_link()  # its control listener's thread too: the error ends the process cleanly
            raise
        if source is None:
            self._close_link()
            return EXIT_OK if stop.is_set() else EXIT_CAMERA_LOST
        # READY only after the first frame went through the pipeline: that first call loads (or, with a cold cache,
        # compiles) the Numba kernels, under TimeoutStartSec; the watchdog only runs from READY on.
        ready_text = f"measuring {source.describe().get('name', '')} -> {self.config.sender.sink}"
        period_s = self.config.sender.status_period_s
        next_status = time.monotonic() + period_s
        timeout_s = self.config.capture.read_timeout_s
        code = EXIT_OK
        try:
            while not stop.is_set():
                self._apply_pending(source)
                try:
                    frame = source.read(timeout_s)
                except CaptureError as exc:
                    _log.error("camera lost: %s", exc)
                    self._send_log(f"camera lost: {exc}", logging.ERROR)
                    self._retire(source)
                    reopened = self._open_camera(stop)
                    if reopened is None:
                        code = EXIT_OK if stop.is_set() else EXIT_CAMERA_LOST
                        break
                    source = reopened
                    self.camera_reopened += 1
                    continue
                if frame is None:
                    if source.finished:
                        _log.info("the recording has ended")
                        break
                elif self._running:
                    self._measure(frame, source)
                else:
                    self.frames_paused += 1
                if frame is not None and self._raw_frame_requested and self.sender is not None:
                    for chunk in split_frame(frame.sequence, frame.image):
                        self.sender.submit(chunk)
                    self._raw_frame_requested = False
                if frame is not None and not self._ready:
                    self.notifier.ready(ready_text)
                    self._ready = True
                self._ping()
                if self._link_broken():
                    self._reopen_link(stop)
                now = time.monotonic()
                if now >= next_status:
                    next_status = now + period_s
                    self._send_status(source)
        finally:
            self.notifier.stopping()
            source.stop()
            self.capture = self._capture_totals(source)
            if self.sender is not None:
                # The last frames' results first (their counts, such as ``budget_cuts``, are the sender's once sent):
                # a Status goes ahead of queued frames, and this one is the run's final word.
                self.sender.wait_sent(_BROKEN_LINK_DRAIN_S if self._link_broken() else 2.0)
                self._send_status(source)
            self._close_link()
        return code
