"""The device pipeline run offline on the host: raw frames in, the FrameResult messages the device would send out.

Used by `ropecam replay --frames` and `ropecam compare` on a frame set, so that raw frames measured now take the
same path (encoding, decoding) as a live stream.
"""

from __future__ import annotations

from pathlib import Path

from ropecam.shared.errors import DataError

__all__ = ["frames_messages"]


def frames_messages(frames: Path, config_path: Path | None = None, device_id: int = 1) -> list[tuple[bytes, int]]:
    """Measure a raw frame set (or image folder, or video) with the device pipeline, offline, and return the
    encoded FrameResult messages as the device would send them, each with its exposure end as receive time.

    As ``ropecam-device extract --config`` and the daemon: the pipeline settings come from the ``[pipeline]`` table
    of a device config file (defaults otherwise), with its ``plane_file`` (the fixed end and material points from
    the plane calibration), and the camera's rolling-shutter readout from ``[capture] readout_us`` (0 = global
    shutter), so every result carries its ``readout_ns``.

    Raises
    ------
    ConfigError
        The config file, its ``readout_us`` (negative, longer than the frame period) or its plane file is bad.
    DataError
        No frames.
    """
    from ropecam.device.capture.sources import open_source
    from ropecam.device.pipeline.config import PipelineConfig
    from ropecam.device.pipeline.pipeline import Pipeline
    from ropecam.device.pipeline.result import to_wire
    from ropecam.shared.config import check_readout, from_mapping, read_toml
    from ropecam.shared.plane import read_plane_file
    from ropecam.shared.protocol import ShapeHint, encode_message

    # Only [pipeline] and [capture] readout_us matter here; the other tables are accepted as they are.
    document = read_toml(config_path) if config_path is not None else {}
    config = from_mapping(PipelineConfig, dict(document.get("pipeline", {})), where=f"{config_path} [pipeline]")
    readout_us = document.get("capture", {}).get("readout_us", 0)
    plane = None if config.plane_file is None else read_plane_file(config.plane_file)
    if plane is not None:
        plane.check_image(plane.image_size)
    source = open_source(frames, None, None)
    check_readout(f"{config_path} [capture] readout_us", readout_us, source.fps)
    pipeline = None
    hint = ShapeHint()
    messages = []
    for sequence, frame in enumerate(source):
        if pipeline is None:
            size = source.image_size or (frame.image.shape[1], frame.image.shape[0])
            pipeline = Pipeline(config, size, readout_us, plane)
        result = pipeline.process(frame.image, frame.index, frame.t_ns, frame.exposure_us)
        data = encode_message(to_wire(result), device_id=device_id, sequence=sequence, t_ns=result.t_end_ns,
                              pack_options={"hint": hint})  # fmt: skip
        messages.append((data, result.t_end_ns))
    if not messages:
        raise DataError(f"{frames}: no frames to measure")
    return messages
