"""The grid kernels' decorator: numba's ``njit``, applied on the first call of any kernel instead of on import.

Importing numba and loading its array math costs about a CPU second. A process that imports the code but never
runs a kernel (``fleet`` checking its input, ``fleet maps``, ``fleet report``, ``--help``) never pays it; the first
kernel call (or :func:`load`, which ``kernels.warm_up`` calls) turns every kernel into its numba dispatcher at once,
so that a kernel calling another is compiled against a dispatcher, and the module attribute of each kernel becomes
that dispatcher. Code that imported a kernel before then holds its :class:`Kernel`, which forwards every call (and
every attribute: ``signatures``, ``py_func``...) to the dispatcher.

A kernel with ``cache=True`` keeps its machine code in the user's cache (:func:`cache_dir`), keyed by the kernels'
source, not beside the source: a new clone, a new environment or a checkout of another branch and back loads
what an earlier one compiled (about 20 CPU seconds) instead of compiling again.
"""

from __future__ import annotations

import functools
import hashlib
import os
import sys
import threading
from collections.abc import Callable
from pathlib import Path
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

        return cast(F, _dispatcher(numba, py_func, options))  # a kernel defined after the load: at once

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
            kernel._dispatcher = _dispatcher(numba, kernel._py_func, kernel.options)
        for kernel in _KERNELS:  # after all of them: no kernel is compiled against a stand-in
            fn = kernel._py_func
            setattr(sys.modules[fn.__module__], fn.__name__, kernel._dispatcher)
        _loaded = True


def _dispatcher(numba: Any, fn: Callable[..., Any], options: dict[str, Any]) -> Any:
    """``numba.njit(**options)(fn)``, its cache (with ``cache=True``) in :func:`cache_dir` when that is writable
    (else beside the source, numba's own place)."""
    dispatcher = numba.njit(**{k: v for k, v in options.items() if k != "cache"})(fn)
    if options.get("cache"):
        shared = _shared_cache(fn)
        if shared is not None:
            dispatcher._cache = shared  # what numba's enable_caching() sets, with our locator first
        else:
            dispatcher.enable_caching()
    return dispatcher


def cache_dir() -> Path:
    """Where the kernels' machine code is kept: ``$FLEET_KERNEL_CACHE``, else the user's cache
    (``$XDG_CACHE_HOME/fleet-emu/kernels``, by default ``~/.cache/fleet-emu/kernels``)."""
    if os.environ.get("FLEET_KERNEL_CACHE"):
        return Path(os.environ["FLEET_KERNEL_CACHE"])
    import platformdirs

    return Path(platformdirs.user_cache_dir("fleet-emu", appauthor=False)) / "kernels"


_CORE = tuple(Path(__file__).with_name(n) for n in ("jit.py", "kernels.py", "cluster_kernels.py", "minpos_kernels.py"))


@functools.cache
def _source_stamp(py_file: str) -> str:
    """The sha256 of a kernel's module and of the core kernel modules, together: a kernel inlines others (from its
    own module or the core's), so a change in any of them recompiles it."""
    digest = hashlib.sha256()
    for path in sorted({Path(py_file), *_CORE}):
        digest.update(path.read_bytes())
    return digest.hexdigest()


def _shared_cache(fn: Callable[..., Any]) -> Any:
    """numba's function cache for ``fn`` in :func:`cache_dir`, stamped with :func:`_source_stamp` of its file
    (numba's own locators after ours: beside the source when the cache folder is not writable); None when
    numba's caching internals are not the ones known here."""
    cache_class = _cache_class()
    if cache_class is None:
        return None
    try:
        return cache_class(fn)
    except Exception:  # any failure here leaves numba's own cache
        return None


@functools.cache
def _cache_class() -> Any:
    """The ``FunctionCache`` subclass that looks in :func:`cache_dir` first (built once), or None."""
    try:
        from numba.core import caching
    except ImportError:
        return None
    base = getattr(caching, "_CacheLocator", None)
    if base is None or not hasattr(caching, "CompileResultCacheImpl") or not hasattr(caching, "FunctionCache"):
        return None

    class Locator(base):  # type: ignore[misc,valid-type]
        def __init__(self, py_func: Callable[..., Any], py_file: str) -> None:
            self._lineno = py_func.__code__.co_firstlineno
            self._file = py_file
            self._path = str(cache_dir())

        def get_cache_path(self) -> str:
            return self._path

        def get_source_stamp(self) -> str:
            return _source_stamp(self._file)

        def get_disambiguator(self) -> str:
            return str(self._lineno)

        @classmethod
        def from_function(cls, py_func: Callable[..., Any], py_file: str) -> Any:
            locator = cls(py_func, py_file)
            try:
                locator.ensure_cache_path()
            except OSError:  # not writable: numba's next locator (beside the source)
                return None
            return locator

    class Impl(caching.CompileResultCacheImpl):
        _locator_classes = [Locator, *caching.CompileResultCacheImpl._locator_classes]

    class Cache(caching.FunctionCache):
        _impl_class = Impl

    return Cache


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
