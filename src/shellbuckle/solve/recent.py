"""A small thread-safe map of the most recently used entries, for the solvers' caches.

The linear solver keeps the fill-reducing orderings of the last few sparsity patterns, and
Newton's method the last KKT assemblers and the last factorization given to each solver; a
Dask worker with several threads may run several runs at once in one process, so each map
takes a lock around every access.
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
