"""The live page of a session (``rv-te dashboard``, ``--dashboard``): its own layer.

A bridge node subscribes to the session's topics (:mod:`.bridge`), a model keeps what the
page shows with min/max envelopes so that no sample is lost on screen (:mod:`.model`,
:mod:`.envelope`), a Starlette app on uvicorn serves the page and its WebSocket
(:mod:`.server`), and foxglove-sdk serves the same topics over the Foxglove WebSocket
protocol (:mod:`.foxglove_relay`). Nothing below the CLI imports this package (import-linter
contract in pyproject.toml); the page (``static/``) ships uPlot with its licence and needs no
internet.
"""
