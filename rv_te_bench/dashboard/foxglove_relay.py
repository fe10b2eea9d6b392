"""The live session over the Foxglove WebSocket protocol (``foxglove-sdk`` from PyPI).

Foxglove and its open fork Lichtblick connect to ``ws://HOST:PORT`` and see the session's
topics as a recorded bag holds them: one channel per topic, ``cdr`` message encoding and the
full ``ros2msg`` schema (:func:`rv_te_bench.io.msgdefs.full_msgdef`, the text the recorder
writes into the bag), the bytes exactly as received from the middleware. No ROS is needed on
the viewing side. The SDK keeps a bounded queue per client (the oldest data message is
dropped when a slow client's queue fills), so a viewer never slows the session.
"""

from __future__ import annotations

import threading
import time
from typing import Any

__all__ = ['FoxglovePortError', 'FoxgloveRelay']


class FoxglovePortError(OSError):
    """The Foxglove WebSocket server could not listen on its port."""


class FoxgloveRelay:
    """A foxglove-sdk WebSocket server and one channel per relayed topic."""

    def __init__(self, *, host: str, port: int, name: str = 'rv-te dashboard') -> None:
        """Start the server (raises :class:`FoxglovePortError` when the port is taken)."""
        import foxglove

        self._foxglove = foxglove
        self._context = foxglove.Context()
        try:
            self.server = foxglove.start_server(name=name, host=host, port=port,
                                                context=self._context,
                                                message_backlog_size=4096)
        except RuntimeError as exc:
            msg = f'Foxglove WebSocket server on {host}:{port}: {exc}'
            raise FoxglovePortError(msg) from None
        self.host = host
        self.port = int(self.server.port)
        self._channels: dict[str, Any] = {}
        self._lock = threading.Lock()
        self.logged = 0

    def add_channel(self, topic: str, type_name: str) -> None:
        """Advertise ``topic`` (resolved name) with its ros2msg schema and cdr encoding."""
        from rv_te_bench.io.msgdefs import full_msgdef

        schema = self._foxglove.Schema(name=type_name, encoding='ros2msg',
                                       data=full_msgdef(type_name).encode())
        with self._lock:
            if topic not in self._channels:
                self._channels[topic] = self._foxglove.Channel(
                    topic, schema=schema, message_encoding='cdr', context=self._context)

    def log(self, topic: str, data: bytes) -> None:
        """Relay one message's CDR bytes (log time: now)."""
        ch = self._channels.get(topic)
        if ch is not None:
            ch.log(data, log_time=time.time_ns())
            self.logged += 1

    def stop(self) -> None:
        """Stop the server and close the channels."""
        with self._lock:
            for ch in self._channels.values():
                ch.close()
            self._channels.clear()
        self.server.stop()
