"""The live page's default ports, apart from the page's server so that the ``rv-te`` parser
(whose launch, test, replay and dashboard commands show them in --help) starts without
importing the server (asyncio, http, email, ssl: ~0.085 CPU s of every ``rv-te`` command)."""

from __future__ import annotations

__all__ = ['DEFAULT_FOXGLOVE_PORT', 'DEFAULT_PORT']

#: The page (HTTP and its WebSocket).
DEFAULT_PORT = 8760
#: The Foxglove WebSocket relay.
DEFAULT_FOXGLOVE_PORT = 8765
