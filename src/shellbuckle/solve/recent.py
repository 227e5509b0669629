"""A small thread-safe map of the most recently used entries, for the solvers' caches.

A PARDISO solver keeps the fill-reducing orderings of the last few sparsity patterns it has
analysed, and a :class:`~.workspace.Workspace` the KKT assemblers of its last few gauges. Each
map belongs to one solver or workspace; a lock around every access keeps one safe where a
caller shares it between threads.
"""

from __future__ import annotations

import threading


class Recent:
    """At most ``size`` entries; :meth:`get` and :meth:`put` make an entry the most recent one,
    and :meth:`put` drops the least recently used beyond ``size``."""

    def __init__(self, size: int):
        self.size = int(size)
        self._items: dict = {}
        self._lock = threading.Lock()

    def get(self, key, default=None):
        """The value of ``key`` (now the most recent entry), or ``default``."""
        with self._lock:
            if key not in self._items:
                return default
            value = self._items[key] = self._items.pop(key)
            return value

    def peek(self, key, default=None):
        """The value of ``key`` without changing the order, or ``default``."""
        with self._lock:
            return self._items.get(key, default)

    def put(self, key, value) -> None:
        """Set ``key`` to ``value`` as the most recent entry."""
        with self._lock:
            self._items.pop(key, None)
            self._items[key] = value
            while len(self._items) > self.size:
                self._items.pop(next(iter(self._items)))

    def clear(self) -> None:
        with self._lock:
            self._items.clear()

    def __len__(self) -> int:
        return len(self._items)
