"""`ropecam monitor --foxglove`: the decoded channels served live to the Foxglove app over its WebSocket protocol.

Uses the official ``foxglove-sdk`` server in its own context (nothing else of the process is published). Every
channel the recording would get (scenes, material points, transforms, status, log, model) is advertised on its
first message, with the same topic, schema and bytes; the raw wire channel is not served (viewers cannot use it).
A client sees only what arrives after it subscribed. Bound to 127.0.0.1 unless another address is given.
"""

from __future__ import annotations

from typing import Any, Final

from ropecam.shared.errors import ConfigError

__all__ = ["DEFAULT_ADDRESS", "FoxgloveLive", "parse_address"]

DEFAULT_ADDRESS: Final = "127.0.0.1:8765"


def parse_address(text: str) -> tuple[str, int]:
    """Return (host, port) of ``HOST:PORT``, ``:PORT`` (127.0.0.1) or ``HOST`` (port 8765).

    Raises
    ------
    ConfigError
        A port that is not an integer in [0, 65535].
    """
    host, _, port_text = text.rpartition(":") if ":" in text else (text, "", "8765")
    host = host.strip("[]") or "127.0.0.1"
    try:
        port = int(port_text)
    except ValueError as exc:
        raise ConfigError(f"--foxglove must be HOST:PORT, e.g. {DEFAULT_ADDRESS}; got {text!r}") from exc
    if not 0 <= port <= 65535:
        raise ConfigError(f"--foxglove port must be in [0, 65535], got {port}")
    return host, port


class FoxgloveLive:
    """A Foxglove WebSocket server that takes the decoded channels (a `ropecam.host.session.Sink`).

    Parameters
    ----------
    host, port
        Address to bind (port 0: any free port; see `port`).

    Raises
    ------
    ConfigError
        ``foxglove-sdk`` is missing, or the address cannot be bound.
    """

    def __init__(self, host: str = "127.0.0.1", port: int = 8765) -> None:
        try:
            import foxglove
        except ImportError as exc:
            raise ConfigError(
                "--foxglove needs the Foxglove SDK: pip install foxglove-sdk (part of ropecam[host])"
            ) from exc
        self._foxglove = foxglove
        self._context = foxglove.Context()
        try:
            self._server = foxglove.start_server(name="ropecam", host=host, port=port, context=self._context)
        except RuntimeError as exc:  # the SDK reports a bind failure as RuntimeError
            raise ConfigError(f"--foxglove {host}:{port}: cannot serve there: {exc}") from exc
        self.host = host
        self._channels: dict[str, Any] = {}
        self.messages = 0

    @property
    def port(self) -> int:
        """The port the server listens on."""
        return int(self._server.port)

    @property
    def url(self) -> str:
        """Address to give the Foxglove app (Open connection -> Foxglove WebSocket)."""
        return f"ws://{self.host}:{self.port}"

    def write(
        self,
        topic: str,
        data: bytes,
        log_time_ns: int,
        schema_name: str | None = None,
        message_encoding: str = "json",
        sequence: int = 0,
        publish_time_ns: int | None = None,
    ) -> bool:
        """Publish one message (same arguments as `ropecam.host.recording.writer.Recorder.write`); True."""
        channel = self._channels.get(topic)
        if channel is None:
            from ropecam.host.recording.schemas import schema_record

            schema = None
            if schema_name is not None:
                schema_encoding, data = schema_record(schema_name, message_encoding)
                schema = self._foxglove.Schema(name=schema_name, encoding=schema_encoding, data=data)
            channel = self._foxglove.Channel(
                topic, schema=schema, message_encoding=message_encoding, context=self._context
            )
            self._channels[topic] = channel
        channel.log(data, log_time=max(0, int(log_time_ns)))
        self.messages += 1
        return True

    def close(self) -> None:
        """Stop the server (clients are disconnected)."""
        for channel in self._channels.values():
            channel.close()
        self._server.stop()
