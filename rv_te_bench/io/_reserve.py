"""The reserve file of a bag being written: room kept for what closing the bag still writes.

When the disk fills, the open ``.mcap`` file must still get its summary and ``metadata.yaml``
its last rewrite. :class:`Reserve` keeps that room allocated in the bag folder
(``.rv_te_reserve``, through :meth:`~._storage.Storage.reserve`): grown to twice the need
once the need passes it (rarely), shrunk to room for the final metadata.yaml when writing
fails, given back when the bag closes. :func:`reserve_need` is the estimate.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from collections.abc import Iterable
    from pathlib import Path

    from rv_te_bench.io._mcap_file import McapFile, TopicInfo
    from rv_te_bench.io._storage import Storage

__all__ = ['RESERVE_MARGIN', 'Reserve', 'reserve_need']

#: Bytes beyond the estimated summary + metadata.yaml.
RESERVE_MARGIN = 64 << 10


def reserve_need(file: McapFile | None, topics: Iterable[TopicInfo], yaml_size: int) -> int:
    """Bytes still to be written when the bag closes now: the open file's summary and a
    metadata.yaml (twice: the temporary copy beside the old one), with a margin."""
    topics = list(topics)
    n_chunks = len(file.chunk_indexes) if file is not None else 0
    per_topic = sum(len(t.msgdef) + 2 * len(t.qos_yaml) + 256 for t in topics)
    return n_chunks * (112 + 10 * len(topics)) + 2 * per_topic + 3 * yaml_size + RESERVE_MARGIN


class Reserve:
    """The reserve file ``path`` and its allocated size [bytes].

    Args:
        storage: The writer's file operations.
        path: The reserve file in the bag folder.
    """

    def __init__(self, storage: Storage, path: Path) -> None:
        self._storage = storage
        self.path = path
        self.size = 0

    def ensure(self, need: int) -> None:
        """Grow to twice ``need`` once the need passes the size.

        Raises:
            OSError: No room for it (the size is unchanged).
        """
        if need > self.size:
            self._storage.reserve(self.path, 2 * need)
            self.size = 2 * need

    def shrink(self, keep: int) -> None:
        """Give back all but ``keep`` bytes (all, if even that fails)."""
        keep = min(self.size, keep)
        try:
            self._storage.reserve(self.path, keep)
            self.size = keep
        except OSError:
            self.release()

    def release(self) -> None:
        """Remove the file (a failure leaves the size as it was)."""
        try:
            self._storage.unlink(self.path)
        except OSError:
            return
        self.size = 0
