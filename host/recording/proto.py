"""The Foxglove well-known messages in protobuf, built with the official ``foxglove-schemas-protobuf`` classes.

Polyline points are stored on a binary grid (2^-7 px = 1/128 px; 2^-17 m = 7.6 um, about 1/128 px on the rig's
plane): a point moves by at most half a step, under a twelfth of the 0.05 px to which the wire's shape code keeps
the device's shapes. The low mantissa bytes of each double are then zero and zstd compresses them away, which makes
a protobuf scene less than half the bytes of the same scene in JSON in the file. The points of a line are
appended as their protobuf encoding made with NumPy in one step (``LinePrimitive.points``, field 5: one
``Point3 {x = 1; y = 2}`` per point; z = 0 is the default and not written), then parsed into the official message:
~80x faster than one ``Point3`` object per point, and the bytes are the ones protobuf itself writes.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any, Final

import numpy as np
from numpy.typing import NDArray

from ropecam.host.recording.convert import (
    POINT_FIELDS,
    POINT_STRIDE,
    JsonEncoder,
    Line,
    SceneContent,
    Transform,
    foxglove_level,
)
from ropecam.shared.errors import ConfigError
from ropecam.shared.protocol.records import Log

__all__ = ["METRE_QUANTUM", "PIXEL_QUANTUM", "ProtobufEncoder", "available", "make_encoder"]

PIXEL_QUANTUM: Final = 2.0**-7
METRE_QUANTUM: Final = 2.0**-17
_POINT: Final = np.dtype(
    [("tag", "u1"), ("length", "u1"), ("x_tag", "u1"), ("x", "<f8"), ("y_tag", "u1"), ("y", "<f8")]
)


def available() -> bool:
    """Say whether the official protobuf schemas (``foxglove-schemas-protobuf``) are installed."""
    try:
        import foxglove_schemas_protobuf.SceneUpdate_pb2  # noqa: F401
    except ImportError:
        return False
    return True


def _points_bytes(points: NDArray[np.float64], quantum: float) -> bytes:
    """Encode (n, 2) points as repeated ``LinePrimitive.points`` fields (tag 0x2a, 18 bytes each)."""
    encoded = np.empty(len(points), dtype=_POINT)
    encoded["tag"], encoded["length"], encoded["x_tag"], encoded["y_tag"] = 0x2A, 18, 0x09, 0x11
    quantized = np.round(np.asarray(points, dtype=np.float64) / quantum) * quantum
    encoded["x"], encoded["y"] = quantized[:, 0], quantized[:, 1]
    return encoded.tobytes()


class ProtobufEncoder:
    """The Foxglove messages as protobuf (official classes); raises ImportError when the package is missing."""

    encoding: Final = "protobuf"

    def __init__(self) -> None:
        from foxglove_schemas_protobuf.FrameTransforms_pb2 import FrameTransforms
        from foxglove_schemas_protobuf.LinePrimitive_pb2 import LinePrimitive
        from foxglove_schemas_protobuf.Log_pb2 import Log as FoxgloveLog
        from foxglove_schemas_protobuf.PackedElementField_pb2 import PackedElementField
        from foxglove_schemas_protobuf.PointCloud_pb2 import PointCloud
        from foxglove_schemas_protobuf.RawImage_pb2 import RawImage
        from foxglove_schemas_protobuf.SceneUpdate_pb2 import SceneUpdate

        self._scene_update = SceneUpdate
        self._line_primitive = LinePrimitive
        self._point_cloud = PointCloud
        self._float32 = PackedElementField.FLOAT32
        self._raw_image = RawImage
        self._log = FoxgloveLog
        self._transforms = FrameTransforms

    def _line(self, line: Line, quantum: float) -> Any:
        primitive = self._line_primitive(thickness=line.thickness, scale_invariant=line.scale_invariant)
        primitive.type = self._line_primitive.LINE_STRIP
        primitive.pose.orientation.w = 1.0
        primitive.color.r, primitive.color.g, primitive.color.b, primitive.color.a = line.color
        primitive.MergeFromString(_points_bytes(line.points, quantum))
        return primitive

    def scene(self, content: SceneContent, t_ns: int) -> bytes:
        """Return a ``foxglove.SceneUpdate`` with one entity (`content`) stamped `t_ns`."""
        quantum = METRE_QUANTUM if content.metres else PIXEL_QUANTUM
        update = self._scene_update()
        entity = update.entities.add(frame_id=content.frame_id, id=content.entity_id)
        entity.timestamp.FromNanoseconds(max(0, int(t_ns)))
        entity.lifetime.FromNanoseconds(0)
        for key, value in content.metadata.items():
            entity.metadata.add(key=key, value=value)
        entity.lines.extend([self._line(line, quantum) for line in content.lines])
        for sphere in content.spheres:
            primitive = entity.spheres.add()
            primitive.pose.position.x = round(sphere.point[0] / quantum) * quantum
            primitive.pose.position.y = round(sphere.point[1] / quantum) * quantum
            primitive.pose.orientation.w = 1.0
            primitive.size.x = primitive.size.y = primitive.size.z = sphere.size
            primitive.color.r, primitive.color.g, primitive.color.b, primitive.color.a = sphere.color
        return update.SerializeToString()

    def point_cloud(self, frame_id: str, packed: bytes, t_ns: int) -> bytes:
        """Return a ``foxglove.PointCloud`` of packed points (`POINT_FIELDS`)."""
        cloud = self._point_cloud(frame_id=frame_id, point_stride=POINT_STRIDE, data=packed)
        cloud.timestamp.FromNanoseconds(max(0, int(t_ns)))
        cloud.pose.orientation.w = 1.0
        for name, offset in POINT_FIELDS:
            cloud.fields.add(name=name, offset=offset, type=self._float32)
        return cloud.SerializeToString()

    def raw_image(self, image: NDArray[np.uint8], device_id: int, t_ns: int) -> bytes:
        """Return a ``foxglove.RawImage`` (mono8) of a grey frame the device sent on request."""
        height, width = image.shape
        message = self._raw_image(
            frame_id=f"device{device_id}/image", width=width, height=height, encoding="mono8", step=width,
            data=np.ascontiguousarray(image).tobytes(),
        )  # fmt: skip
        message.timestamp.FromNanoseconds(max(0, int(t_ns)))
        return message.SerializeToString()

    def log(self, record: Log, name: str, t_ns: int) -> bytes:
        """Return a ``foxglove.Log`` for a device log line; `name` says who logged it."""
        message = self._log(level=foxglove_level(record.level), message=record.text, name=name)
        message.timestamp.FromNanoseconds(max(0, int(t_ns)))
        return message.SerializeToString()

    def transforms(self, transforms: Sequence[Transform], t_ns: int) -> bytes:
        """Return a ``foxglove.FrameTransforms``."""
        message = self._transforms()
        for t in transforms:
            item = message.transforms.add(parent_frame_id=t.parent, child_frame_id=t.child)
            item.timestamp.FromNanoseconds(max(0, int(t_ns)))
            item.translation.x, item.translation.y, item.translation.z = t.translation
            item.rotation.x, item.rotation.y, item.rotation.z, item.rotation.w = t.rotation
        return message.SerializeToString()


def make_encoder(encoding: str | None = None) -> JsonEncoder | ProtobufEncoder:
    """Return the encoder of `encoding` (``json``, ``protobuf``; None: protobuf when installed, else JSON).

    Raises
    ------
    ConfigError
        An unknown encoding, or ``protobuf`` without ``foxglove-schemas-protobuf`` installed.
    """
    if encoding is None:
        return ProtobufEncoder() if available() else JsonEncoder()
    if encoding == "json":
        return JsonEncoder()
    if encoding == "protobuf":
        if not available():
            raise ConfigError(
                "--encoding protobuf needs the official schemas: pip install foxglove-schemas-protobuf "
                "(part of ropecam[host]); or record with --encoding json"
            )
        return ProtobufEncoder()
    raise ConfigError(f"--encoding must be json or protobuf, got {encoding!r}")
