"""Host load: N simulated devices stream FrameResults into one `ropecam monitor --record`; loss and host CPU time.

N simulated devices (separate processes) stream real encoded FrameResults over UDP loopback into one
`ropecam monitor --record` process; report the loss and the host's CPU time.

    python tools/bench.py host [--devices 8] [--fps 119] [--duration-s 10] [--json]

Loss = messages the senders handed to the socket minus raw messages in the recording (every received packet is
recorded, so this is end-to-end loss). Host CPU = user + system time of the monitor process (os.wait4) over its
whole run, and the median of the per-second CPU readings the monitor prints while the devices stream. Decoded
fraction = FrameResults with a decoded scene / FrameResults received (the monitor sheds full decodes under load;
the raw channel is always complete).
"""

from __future__ import annotations

import argparse
import json
import multiprocessing as mp
import os
import re
import signal
import socket
import statistics
import tempfile
import time
from collections import Counter
from pathlib import Path


def _sender(device_id: int, port: int, fps: float, duration_s: float, ready: mp.Barrier, results: mp.Queue) -> None:
    from ropecam.host.sim.stream import SimulatedDevice
    from ropecam.shared.transport import open_transport

    device = SimulatedDevice(device_id, fps, frame_count=24, seed=device_id)
    messages = list(device.messages(round(duration_s * fps)))
    with open_transport(f"udp://127.0.0.1:{port}") as link:
        ready.wait()  # every sender has encoded its frames: start together
        begin = time.monotonic()
        begin_wall = time.time()
        late = 0.0
        for offset_s, data in messages:
            delay = begin + offset_s - time.monotonic()
            if delay > 0:
                time.sleep(delay)
            else:
                late = max(late, -delay)
            link.send(data)
        results.put((device_id, link.stats.sent, link.stats.send_dropped, late, begin_wall, time.time()))


def _free_port() -> int:
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as probe:
        probe.bind(("127.0.0.1", 0))
        return probe.getsockname()[1]


def run_once(devices: int, fps: float, duration_s: float, workdir: Path, decode: str = "auto") -> dict:
    """Run the benchmark once and return its figures."""
    from mcap.reader import make_reader

    from ropecam.host.monitor.process import MonitorProcess

    port = _free_port()
    record = workdir / "bench.mcap"
    # Output into files and a start that waits with a timeout (MonitorProcess): never a pipe nobody reads.
    monitor = MonitorProcess(
        ["--no-ui", "--source", f"udp://127.0.0.1:{port}?listen=1", "--record", str(record), "--decode", decode],
        log_dir=workdir,
    )
    monitor_start = time.time()
    results: mp.Queue = mp.Queue()
    ready = mp.Barrier(devices)
    senders = [mp.Process(target=_sender, args=(k + 1, port, fps, duration_s, ready, results)) for k in range(devices)]
    for process in senders:
        process.start()
    sent = {}
    for _ in senders:
        device_id, count, dropped, late, begin, end = results.get(timeout=duration_s + 300)
        sent[device_id] = (count, dropped, late, begin, end)
    for process in senders:
        process.join()
    time.sleep(1.0)  # the last datagrams reach the host
    monitor.process.send_signal(signal.SIGTERM)
    deadline = time.monotonic() + 120.0
    while (waited := os.wait4(monitor.pid, os.WNOHANG))[0] == 0:  # with rusage, but never forever
        if time.monotonic() > deadline:
            monitor.kill()
            raise SystemExit(f"monitor did not exit 120 s after SIGTERM: {monitor.stderr_path.read_text()}")
        time.sleep(0.05)
    _, status, usage = waited
    host_wall_s = time.time() - monitor_start
    monitor.process.returncode = os.waitstatus_to_exitcode(status)
    err = monitor.stderr_path.read_text()
    out = monitor.stdout_path.read_text()
    if monitor.process.returncode != 0:
        raise SystemExit(f"monitor failed ({monitor.process.returncode}): {err}")
    stream_from = max(v[3] for v in sent.values()) - monitor_start
    stream_to = min(v[4] for v in sent.values()) - monitor_start
    received: Counter[int] = Counter()
    scenes: Counter[str] = Counter()
    from ropecam.shared.protocol.wire import MessageType, peek_header

    frames: Counter[int] = Counter()
    with open(record, "rb") as handle:
        for _, channel, message in make_reader(handle).iter_messages(log_time_order=False):
            if channel.topic == "/ropecam/wire":
                header = peek_header(message.data)
                received[header.device_id] += 1
                frames[header.device_id] += header.type == MessageType.FRAME_RESULT
            else:
                scenes[channel.topic] += 1
    per_device = {
        device_id: {
            "sent": count,
            "send_dropped": dropped,
            "received": received[device_id],
            "lost": count - received[device_id],
            "sender_max_late_ms": round(late * 1e3, 1),
            "decoded_fraction": round(scenes[f"/device{device_id}/image/scene"] / max(1, frames[device_id]), 3),
        }
        for device_id, (count, dropped, late, _, _) in sorted(sent.items())
    }
    cpu_s = usage.ru_utime + usage.ru_stime
    streaming = []  # the monitor's own per-second CPU readings while all devices stream
    for line in out.splitlines():
        match = re.match(r"t=\s*([\d.]+)s cpu\s+(\d+)%", line)
        if match and stream_from + 1.0 <= float(match.group(1)) <= stream_to - 0.5:
            streaming.append(float(match.group(2)))
    return {
        "devices": devices,
        "decode": decode,
        "fps": fps,
        "duration_s": duration_s,
        "messages_sent": sum(d["sent"] for d in per_device.values()),
        "messages_lost": sum(d["lost"] for d in per_device.values()),
        "host_cpu_s": round(cpu_s, 2),
        "host_wall_s": round(host_wall_s, 2),
        "host_cpu_percent_streaming_median": statistics.median(streaming) if streaming else None,
        "host_cpu_percent_streaming_max": max(streaming) if streaming else None,
        "host_max_rss_mb": round(usage.ru_maxrss / 1024, 1),
        "recording_mb": round(record.stat().st_size / 1e6, 2),
        "decoded_fraction": round(
            sum(scenes[f"/device{k}/image/scene"] for k in sent) / max(1, sum(frames.values())), 3
        ),
        "per_device": per_device,
        "monitor_final_lines": [line for line in out.splitlines() if line.startswith("final")],
    }


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Add this subcommand's options to `parser`."""
    parser.add_argument("--devices", type=int, default=8)
    parser.add_argument("--fps", type=float, default=119.0)
    parser.add_argument("--duration-s", type=float, default=10.0)
    parser.add_argument("--decode", choices=("auto", "all", "none"), default="auto", help="monitor --decode mode")
    parser.add_argument("--json", action="store_true", help="print the figures as JSON")


def run(args: argparse.Namespace) -> int:
    """Run the subcommand with the parsed `args`; return the exit code."""
    with tempfile.TemporaryDirectory() as workdir:
        figures = run_once(args.devices, args.fps, args.duration_s, Path(workdir), args.decode)
    if args.json:
        print(json.dumps(figures, indent=2))
        return 0
    print(
        f"{figures['devices']} devices x {figures['fps']:g} FPS for {figures['duration_s']:g} s, decode "
        f"{figures['decode']}: "
        f"sent {figures['messages_sent']}, lost {figures['messages_lost']}; host CPU {figures['host_cpu_s']} s in "
        f"{figures['host_wall_s']} s wall (incl. startup and sender setup); while streaming "
        f"{figures['host_cpu_percent_streaming_median']}% of a core (median, max "
        f"{figures['host_cpu_percent_streaming_max']}%); decoded {figures['decoded_fraction']:.0%} of frames; "
        f"recording {figures['recording_mb']} MB"
    )
    for device_id, figures_device in figures["per_device"].items():
        print(f"  device {device_id}: {figures_device}")
    return 0 if figures["messages_lost"] == 0 else 1
