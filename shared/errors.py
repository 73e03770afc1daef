"""Exception hierarchy of ropecam: everything we raise on purpose derives from `RopecamError`."""


class RopecamError(Exception):
    """Root of every error ropecam raises on purpose; applications turn it into a message and an exit code."""


class ConfigError(RopecamError):
    """A configuration file, key or value is invalid (the message names the file, key and value)."""


class CaptureError(RopecamError):
    """A frame source failed: camera lost, frame set unreadable, format not supported."""


class TransportError(RopecamError):
    """A transport (serial, UDP, loop) failed to open, read or write."""


class ProtocolError(RopecamError):
    """Bytes on the wire are not a valid message: magic, version, length or CRC."""


class ModelError(RopecamError):
    """The cable model cannot be set up or solved (e.g. Newton did not converge)."""


class CalibrationError(RopecamError):
    """Camera or plane calibration failed or its inputs are inconsistent."""


class DataError(RopecamError):
    """A data file (frame set, recording, result file) is missing, malformed or inconsistent."""


class UsageError(RopecamError):
    """The command line asks for something that cannot be done as asked (e.g. an output exists, no --force)."""
