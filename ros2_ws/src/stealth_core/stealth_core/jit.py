"""Compiling plain-Python loops with numba, cached once per machine; without numba they stay
plain Python (the same numbers, slowly), and :func:`import_problem` says why.

``jit`` compiles a kernel (``numba.njit(cache=True)``); ``jitable`` leaves a function plain
Python for Python callers and lets kernels call it, compiled into them (one source for both).

Why a cache stamp of its own: numba checks a cached kernel against its own source file only,
so a kernel that calls functions of other modules would keep running their old code after
they change. Here a kernel's cache holds while no source file of its top-level package
(``stealth_sim``, ``stealth_core``) nor of ``stealth_core`` (whose jitable functions, such as the
controller's, kernels of other packages compile in) changed: any edit there recompiles the
kernels at their next use (``make setup`` warms them again).
"""

import functools
import hashlib
import logging
import os

LOG = logging.getLogger('stealth_core.jit')

try:
    import numba
    from numba.core import caching, config
    from numba.extending import register_jitable
except ImportError as exc:  # pragma: no cover - numba is pinned in requirements.lock
    numba = None
    _IMPORT_PROBLEM = f'numba is not importable ({exc})'
else:
    _IMPORT_PROBLEM = None


def import_problem() -> str | None:
    """Why nothing can be compiled (numba missing), or None."""
    return _IMPORT_PROBLEM


def _package_root(path: str) -> str:
    """The directory of the top-level package ``path`` belongs to."""
    directory = os.path.dirname(path)
    while os.path.exists(os.path.join(os.path.dirname(directory), '__init__.py')):
        directory = os.path.dirname(directory)
    return directory


@functools.cache
def _package_hash(root: str, stamps: tuple) -> bytes:
    """The sources of a package, hashed (memoised on their (path, mtime, size) stamps)."""
    digest = hashlib.sha256()
    for path, _, _ in stamps:
        digest.update(path.encode())
        with open(path, 'rb') as source:
            digest.update(source.read())
    return digest.digest()


# This package's own root: its jitable functions are compiled into other packages' kernels.
_CORE_ROOT = os.path.dirname(os.path.realpath(__file__))


def _package_stamp(root: str) -> bytes:
    stamps = []
    for directory, subdirectories, files in os.walk(root):
        subdirectories[:] = sorted(d for d in subdirectories if d != '__pycache__')
        for name in sorted(files):
            if name.endswith('.py'):
                path = os.path.join(directory, name)
                status = os.stat(path)
                stamps.append((path, status.st_mtime_ns, status.st_size))
    return _package_hash(root, tuple(stamps))


if numba is not None:

    class _PackageCacheLocator(caching.InTreeCacheLocator):
        """numba's in-tree cache (``__pycache__`` beside the source), stamped with the whole
        package's sources rather than the one file's: for the kernels ``jit`` makes (marked
        ``_jit_package``) unless ``NUMBA_CACHE_DIR`` is set; any other numba user in the
        process keeps numba's own locators."""

        @classmethod
        def from_function(cls, py_func, py_file):
            if config.CACHE_DIR or not getattr(py_func, '_jit_package', False):
                return None
            return super().from_function(py_func, py_file)

        def get_source_stamp(self):
            roots = dict.fromkeys((_package_root(self._py_file), _CORE_ROOT))
            return b''.join(_package_stamp(root) for root in roots)

    # A numba internal (0.68, pinned): a later numba without it keeps its per-file stamps,
    # and says so, rather than failing every import.
    _LOCATORS = getattr(caching.CacheImpl, '_locator_classes', None)
    if _LOCATORS is None:
        LOG.warning(
            'numba %s has no CacheImpl._locator_classes: cached kernels are checked against '
            'their own file only (after editing a kernel module, delete the *.nbi and *.nbc '
            'files in its __pycache__)',
            numba.__version__,
        )
    elif _PackageCacheLocator not in _LOCATORS:
        _LOCATORS.insert(0, _PackageCacheLocator)


def _njit(function):
    """``numba.njit(cache=True)``, or without the cache when numba has nowhere to write it.

    The cache sits beside the source file the code object names: the real file, so that the
    colcon install (symlinks) and the source tree share one cache.
    """
    code = function.__code__
    function.__code__ = code.replace(co_filename=os.path.realpath(code.co_filename))
    function._jit_package = True
    try:
        return numba.njit(cache=True, error_model='numpy')(function)
    except RuntimeError as exc:  # numba: "cannot cache function ...: no locator available"
        LOG.warning('numba cannot cache %s (%s); it compiles in every process', function, exc)
        return numba.njit(error_model='numpy')(function)


def _identity(function):
    return function


jit = _identity if numba is None else _njit
jitable = _identity if numba is None else register_jitable
