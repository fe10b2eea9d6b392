"""One dashboard: the model, the web server, the Foxglove relay and the bridge node.

Used by ``rv-te dashboard`` (in the foreground) and by ``--dashboard`` on ``rv-te launch``,
``rv-te test`` and ``rv-te replay`` (beside the session, in threads of the same process, on
a ROS context of its own).
"""

from __future__ import annotations

import contextlib
import ipaddress
import secrets
import socket
import sys
import threading
from dataclasses import dataclass
from typing import Any

from rv_te_bench.dashboard.model import DashboardModel
from rv_te_bench.dashboard.ports import DEFAULT_FOXGLOVE_PORT, DEFAULT_PORT
from rv_te_bench.dashboard.server import HttpServer, bind_socket, create_app

__all__ = ['DEFAULT_FOXGLOVE_PORT', 'DEFAULT_PORT', 'Dashboard', 'DashboardOptions']


def is_loopback(host: str) -> bool:
    """True for 127.0.0.0/8, ::1 and 'localhost'."""
    if host == 'localhost':
        return True
    try:
        return ipaddress.ip_address(host).is_loopback
    except ValueError:
        return False


@dataclass(frozen=True)
class DashboardOptions:
    """Where and what the dashboard serves."""

    namespace: str = '/'
    host: str = '127.0.0.1'
    port: int = DEFAULT_PORT
    token: str | None = None          # None: made up when the host is not loopback
    foxglove_port: int | None = DEFAULT_FOXGLOVE_PORT   # None: no Foxglove server
    source: str = 'live'

    def __post_init__(self) -> None:
        """Check the ports."""
        for name in ('port', 'foxglove_port'):
            v = getattr(self, name)
            if v is not None and not 0 <= v <= 65535:
                msg = f'{name} must be 0..65535, got {v!r}'
                raise ValueError(msg)


class Dashboard:
    """Start with :meth:`start`, stop with :meth:`stop` (or use as a context manager)."""

    def __init__(self, options: DashboardOptions) -> None:
        """Nothing runs until :meth:`start`."""
        self.options = options
        self.token = options.token
        if self.token is None and not is_loopback(options.host):
            self.token = secrets.token_urlsafe(18)
        self.model = DashboardModel(namespace=options.namespace or '/', source=options.source)
        self.http: HttpServer | None = None
        self.relay: Any = None
        self.port = options.port
        self._ctx: Any = None
        self._thread: threading.Thread | None = None
        self.bridge: Any = None

    def start(self) -> None:
        """Bind the ports (PortInUseError / FoxglovePortError first), then serve and subscribe.

        Raises:
            PortInUseError: The page's port is taken.
            FoxglovePortError: The Foxglove port is taken.
        """
        sock = bind_socket(self.options.host, self.options.port)
        self.port = sock.getsockname()[1]
        try:
            if self.options.foxglove_port is not None:
                from rv_te_bench.dashboard.foxglove_relay import FoxgloveRelay

                # the Foxglove protocol has no access token: it stays on this machine unless
                # the page itself is on loopback too (then both are on the same host)
                fox_host = self.options.host if is_loopback(self.options.host) else '127.0.0.1'
                self.relay = FoxgloveRelay(host=fox_host, port=self.options.foxglove_port)
        except Exception:
            sock.close()
            raise
        app, self.hub = create_app(self.model, token=self.token)
        self.http = HttpServer(app, sock)
        self.http.start()
        self._start_bridge()

    def _start_bridge(self) -> None:
        import rclpy
        from rclpy.signals import SignalHandlerOptions

        from rv_te_bench.dashboard.bridge import DashboardBridge
        from rv_te_bench.nodes.common import make_executor

        self._ctx = rclpy.context.Context()
        rclpy.init(context=self._ctx, signal_handler_options=SignalHandlerOptions.NO)
        ns = self.options.namespace if self.options.namespace not in {'', '/'} else '/'
        self.bridge = DashboardBridge(self.model, relay=self.relay, context=self._ctx,
                                      namespace=ns)
        executor = make_executor('events', context=self._ctx)
        executor.add_node(self.bridge)
        ctx = self._ctx

        def spin() -> None:
            with contextlib.suppress(Exception):
                while ctx.ok():
                    executor.spin_once(timeout_sec=0.1)
            with contextlib.suppress(Exception):
                executor.shutdown()

        self._thread = threading.Thread(target=spin, name='dashboard-ros', daemon=True)
        self._thread.start()

    def urls(self) -> list[str]:
        """The page's address(es), with the token where one is needed."""
        q = f'?token={self.token}' if self.token else ''
        host = self.options.host
        if host in {'0.0.0.0', '::'}:
            return [f'http://{socket.gethostname()}:{self.port}/{q}',
                    f'http://127.0.0.1:{self.port}/{q}']
        shown = f'[{host}]' if ':' in host else host
        return [f'http://{shown}:{self.port}/{q}']

    def announce(self, stream: Any = None) -> None:
        """Say where the page is (and the Foxglove server) on stderr."""
        stream = stream or sys.stderr
        for url in self.urls():
            print(f'dashboard: {url}', file=stream)
        if self.token:
            print('dashboard: the link carries its access token; without it the page '
                  'answers 403', file=stream)
        if self.relay is not None:
            print(f'dashboard: Foxglove / Lichtblick: ws://{self.relay.host}:{self.relay.port} '
                  '(layout docs/foxglove_te_session.json)', file=stream)
        stream.flush()

    def stop(self) -> None:
        """Stop the bridge, the relay and the server (open tabs keep what they show)."""
        if self._ctx is not None:
            import rclpy

            with contextlib.suppress(Exception):
                rclpy.try_shutdown(context=self._ctx)
            if self._thread is not None:
                self._thread.join(timeout=5.0)
            with contextlib.suppress(Exception):
                self.bridge.destroy_node()
            self._ctx = None
        if self.relay is not None:
            with contextlib.suppress(Exception):
                self.relay.stop()
            self.relay = None
        if self.http is not None:
            self.http.stop()
            self.http = None

    def __enter__(self) -> Dashboard:
        """Start."""
        self.start()
        return self

    def __exit__(self, *exc: object) -> None:
        """Stop."""
        self.stop()
