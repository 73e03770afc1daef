"""Fuzz the message decoder and the serial deframer with random and mutated inputs.

Every input goes into `decode_message` (only `ProtocolError` may come out) and, as a byte stream, into a `Deframer`
(nothing may come out of `feed`; each frame it yields goes into `decode_message` again). Half of the mutants get their
CRC (and length field) repaired, so the record parsers behind the CRC are exercised too, not only the CRC check.
A hang is caught by a per-input watchdog (SIGALRM).

    python tools/fuzz.py protocol --count 1000000 --seed 1 [--json]
"""

from __future__ import annotations

import argparse
import contextlib
import json
import random
import signal
import struct
import sys
import time
import traceback
import zlib

from ropecam.shared.errors import ProtocolError
from ropecam.shared.protocol import Deframer, Signer, encode_message, frame
from ropecam.shared.protocol.examples import example_records
from ropecam.shared.protocol.wire import CRC_BYTES, HEADER_BYTES, decode_message


def seeds() -> list[bytes]:
    """Valid messages of every type (plus an authenticated control message)."""
    out = []
    for index, record in enumerate(example_records().values()):
        out.append(encode_message(record, device_id=index, sequence=index, t_ns=10**18 + index))
    control = example_records()[next(iter(t for t in example_records() if t.name == "CONTROL"))]
    out.append(encode_message(control, device_id=1, sequence=9, t_ns=0, signer=Signer(bytes(32), lambda: 5)))
    return out


def repair(data: bytearray) -> bytes:
    """Fix the length field and the CRC so the mutant reaches the record parser."""
    if len(data) >= HEADER_BYTES + CRC_BYTES:
        trailer = 24 if data[4] & 1 else 0
        length = len(data) - HEADER_BYTES - CRC_BYTES - trailer
        if 0 <= length <= 0xFFFF:
            struct.pack_into("<H", data, 19, length)
        body = bytes(data[:-CRC_BYTES])
        return body + struct.pack("<I", zlib.crc32(body))
    return bytes(data)


def mutate(rng: random.Random, corpus: list[bytes]) -> bytes:
    """Return one random or mutated input."""
    choice = rng.random()
    if choice < 0.1:
        return rng.randbytes(rng.randint(0, 300))
    data = bytearray(rng.choice(corpus))
    for _ in range(rng.choice((1, 1, 1, 2, 3, 8))):
        op = rng.randrange(7)
        position = rng.randrange(len(data) + 1)
        if op == 0 and data:  # bit flip
            data[min(position, len(data) - 1)] ^= 1 << rng.randrange(8)
        elif op == 1 and data:  # byte replace, often with an interesting value
            data[min(position, len(data) - 1)] = rng.choice((0, 1, 0x7F, 0x80, 0xFF, rng.randrange(256)))
        elif op == 2:  # insert
            data[position:position] = rng.randbytes(rng.randint(1, 8))
        elif op == 3 and data:  # delete a run
            del data[position : position + rng.randint(1, 8)]
        elif op == 4:  # truncate
            del data[position:]
        elif op == 5:  # splice with another message
            other = rng.choice(corpus)
            data[position:] = other[rng.randrange(len(other)) :]
        elif op == 6 and len(data) > 8:  # overwrite a varint-looking run with 0xFF continuation bytes
            data[position : position + 4] = b"\xff\xff\xff\x7f"
    return repair(data) if rng.random() < 0.5 else bytes(data)


class Hang(Exception):
    """Raised by the watchdog."""


def _alarm(signum: int, frame_: object) -> None:
    raise Hang


def fuzz(count: int, seed: int, timeout_s: float = 2.0, progress: bool = True) -> dict[str, object]:
    """Fuzz `count` inputs; return counts, time and the worst per-input time. Raises on any finding."""
    rng = random.Random(seed)
    corpus = seeds()
    outcomes = {"decoded": 0, "protocol_error": 0, "deframed_frames": 0}
    deframer = Deframer()
    signal.signal(signal.SIGALRM, _alarm)
    start = time.perf_counter()
    worst_s = 0.0
    for index in range(count):
        data = mutate(rng, corpus)
        began = time.perf_counter()
        signal.setitimer(signal.ITIMER_REAL, timeout_s)
        try:
            try:
                decode_message(data)
                outcomes["decoded"] += 1
            except ProtocolError:
                outcomes["protocol_error"] += 1
            # The stream side: raw bytes (as garbage on the line) and the framed input.
            stream = data if index % 2 else frame(data)
            for chunk in deframer.feed(stream):
                outcomes["deframed_frames"] += 1
                with contextlib.suppress(ProtocolError):
                    decode_message(chunk)
        except Hang:
            raise SystemExit(f"HANG: input {index} took > {timeout_s} s: {data.hex()}") from None
        except Exception:
            traceback.print_exc()
            raise SystemExit(f"FINDING: input {index} raised a non-ProtocolError: {data.hex()}") from None
        finally:
            signal.setitimer(signal.ITIMER_REAL, 0)
        worst_s = max(worst_s, time.perf_counter() - began)
        if progress and index and index % 100_000 == 0:
            elapsed = time.perf_counter() - start
            print(f"  {index:>9,d} inputs  {elapsed:7.1f} s  ({index / elapsed:,.0f}/s)", file=sys.stderr)
    elapsed = time.perf_counter() - start
    return {
        "inputs": count,
        "seed": seed,
        "seconds": round(elapsed, 2),
        "inputs_per_second": round(count / elapsed),
        "worst_input_ms": round(worst_s * 1e3, 3),
        **outcomes,
        "deframer_bad_frames": deframer.stats.bad_frames,
        "deframer_overlong": deframer.stats.overlong,
        "findings": 0,
    }


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Add this subcommand's options to `parser`."""
    parser.add_argument("--count", type=int, default=1_000_000, help="number of inputs (default 1e6)")
    parser.add_argument("--seed", type=int, default=1, help="random seed (default 1)")
    parser.add_argument("--timeout-s", type=float, default=2.0, help="per-input hang limit (default 2 s)")
    parser.add_argument("--json", action="store_true", help="print the result as JSON")


def run(args: argparse.Namespace) -> int:
    """Run the subcommand with the parsed `args`; return the exit code."""
    result = fuzz(args.count, args.seed, args.timeout_s, progress=not args.json)
    if args.json:
        print(json.dumps(result))
    else:
        print(
            f"{result['inputs']:,d} inputs in {result['seconds']} s ({result['inputs_per_second']:,d}/s), "
            f"worst input {result['worst_input_ms']} ms: {result['decoded']:,d} decoded, "
            f"{result['protocol_error']:,d} ProtocolError, {result['deframed_frames']:,d} frames deframed; "
            "no other exception, no hang"
        )
    return 0
