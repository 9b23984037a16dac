"""numba's njit when numba is installed (extra "fast"), else a no-op stand-in: the decorated functions then
run as plain (slow) Python. Every numba-compiled function of the simulator takes its njit from here."""

from __future__ import annotations

try:
    from numba import njit
except ImportError:  # pragma: no cover - numba is optional (extra "fast")

    def njit(*args, **kwargs):  # type: ignore[no-redef]  # noqa: ANN002, ANN003, ANN201
        """No-op stand-in for numba.njit."""
        if args and callable(args[0]):
            return args[0]
        return lambda function: function


__all__ = ["njit"]
