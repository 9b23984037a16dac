"""The one way this project compiles a function: numba's njit with the project's settings.

Every compiled law of both programs is written once, as plain Python that numba can compile, and decorated
here. numba is a required dependency (pyproject.toml): it has wheels for every platform we support, and the
control loops need it to keep time. `NUMBA_DISABLE_JIT=1` in the environment runs the very same functions as
plain Python (numba's own switch), which is how the tests show that compiled and interpreted runs fly the
same (tests/swarm_common/test_jit.py, tests/gcs_swarm/guidance/test_interpreted_tick.py).

Settings: `cache=True` (numba's on-disk cache: a later process loads the machine code instead of compiling),
`error_model="numpy"` (x / 0 gives inf or NaN as in numpy, no ZeroDivisionError), never fastmath (it would
reorder and contract floating-point operations, so results would depend on the compiler).
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any, TypeVar

from numba import njit

F = TypeVar("F", bound=Callable[..., Any])

_SETTINGS: dict[str, Any] = {"cache": True, "error_model": "numpy"}


def kernel(function: F) -> F:
    """Compile `function` with the project's settings (lazily, on its first call, or from the cache)."""
    return njit(**_SETTINGS)(function)  # type: ignore[no-any-return]


def kernel_with(signature: str) -> Callable[[F], F]:
    """Compile eagerly for one numba `signature` (e.g. "float64(float64, float64)"), at import."""

    def decorate(function: F) -> F:
        return njit(signature, **_SETTINGS)(function)  # type: ignore[return-value]

    return decorate


__all__ = ["kernel", "kernel_with"]
