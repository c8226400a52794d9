"""The grid kernels' decorator: numba's ``njit``, applied on the first call of any kernel instead of on import.

Importing numba and loading its array math costs about a CPU second. A process that imports the code but never
runs a kernel (``fleet`` checking its input, ``fleet maps``, ``fleet report``, ``--help``) never pays it; the first
kernel call (or :func:`load`, which ``kernels.warm_up`` calls) turns every kernel into its numba dispatcher at once,
so that a kernel calling another is compiled against a dispatcher, and the module attribute of each kernel becomes
that dispatcher. Code that imported a kernel before then holds its :class:`Kernel`, which forwards every call (and
every attribute: ``signatures``, ``py_func``...) to the dispatcher.
"""

from __future__ import annotations

import functools
import sys
import threading
from collections.abc import Callable
from typing import Any, TypeVar, cast

F = TypeVar("F", bound=Callable[..., Any])

_KERNELS: list[Kernel] = []
_LOCK = threading.Lock()
_loaded = False


class Kernel:
    """A kernel until :func:`load`: its Python function and the options ``numba.njit`` will get."""

    def __init__(self, py_func: Callable[..., Any], options: dict[str, Any]) -> None:
        functools.update_wrapper(self, py_func)
        self.options = options
        self._py_func = py_func
        self._dispatcher: Any = None

    @property
    def dispatcher(self) -> Any:
        """numba's dispatcher for this kernel (every kernel's is made on the first request)."""
        if self._dispatcher is None:
            load()
        return self._dispatcher

    def __call__(self, *args: Any, **kwargs: Any) -> Any:
        return self.dispatcher(*args, **kwargs)

    def __getattr__(self, name: str) -> Any:
        if name.startswith("__"):  # copy, pickle and inspect probe dunders: never a reason to load numba
            raise AttributeError(name)
        return getattr(self.dispatcher, name)


def njit(**options: Any) -> Callable[[F], F]:
    """``numba.njit(**options)``, deferred to the first call of any kernel."""

    def wrap(py_func: F) -> F:
        with _LOCK:
            if not _loaded:
                kernel = Kernel(py_func, options)
                _KERNELS.append(kernel)
                return cast(F, kernel)
        import numba

        return cast(F, numba.njit(**options)(py_func))

    return wrap


def load() -> None:
    """Import numba and make every kernel its dispatcher (each compiles, or loads from numba's cache, on its first
    call with new argument types); the kernels' modules then hold the dispatchers. Idempotent, thread-safe."""
    global _loaded
    with _LOCK:
        if _loaded:
            return
        import numba

        _load_array_math()
        for kernel in _KERNELS:
            fn = kernel._py_func
            kernel._dispatcher = numba.njit(**kernel.options)(fn)
        for kernel in _KERNELS:  # after all of them: no kernel is compiled against a stand-in
            fn = kernel._py_func
            setattr(sys.modules[fn.__module__], fn.__name__, kernel._dispatcher)
        _loaded = True


def loaded() -> bool:
    """Whether numba has been imported for the kernels (:func:`load` ran)."""
    return _loaded


def _load_array_math() -> None:
    """Load numba's array math with scipy's BLAS hidden.

    Its import checks for a BLAS by importing ``scipy.linalg``, which brings ``numpy.f2py`` with it: about half a
    CPU second in every process that runs a kernel, the launcher and the fork server of every run included. The
    check decides only whether ``np.correlate`` and ``np.convolve`` of floats call BLAS (no kernel here does);
    ``np.dot`` and ``np.linalg`` look for BLAS again when compiled, and find it.
    """
    blas = "scipy.linalg.cython_blas"
    if "numba.np.arraymath" in sys.modules or blas in sys.modules:
        return  # loaded, or scipy.linalg is: the check costs nothing more
    sys.modules[blas] = None  # type: ignore[assignment]  # ``import scipy.linalg.cython_blas`` fails at once
    try:
        import numba.np.arraymath  # noqa: F401
    finally:
        del sys.modules[blas]
