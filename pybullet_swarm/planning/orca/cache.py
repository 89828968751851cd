"""Compiled kernels of the ORCA package, cached on disk and invalidated by any change to the package.

numba's on-disk cache checks only the source file of the function it compiled, yet a kernel
inlines the functions and constants it calls from other files: after an edit of ``core.py`` the
cached kernel of ``kernel.py`` would still run the old core. So every function of this package is
compiled with ``njit`` below, whose cache stamp covers every source file of the package.
"""

from __future__ import annotations

import functools
import os
from pathlib import Path
from typing import Any, Callable, TypeVar, cast

import numba
import numba.core.caching as _caching

F = TypeVar("F", bound=Callable[..., Any])

_PACKAGE = Path(__file__).resolve().parent


@functools.lru_cache(maxsize=1)
def _package_stamp() -> tuple[tuple[str, int, int], ...]:
    """(name, mtime ns, size) of every source file of the package."""
    return tuple((p.name, p.stat().st_mtime_ns, p.stat().st_size) for p in sorted(_PACKAGE.glob("*.py")))


def _stamped(base: type) -> type:
    """A numba cache locator like ``base`` for this package's files, stamped with the whole package."""

    class PackageLocator(base):  # type: ignore[misc, valid-type]
        @classmethod
        def from_function(cls, py_func: Any, py_file: str) -> Any:
            if Path(os.path.abspath(py_file)).parent != _PACKAGE:
                return None
            return super().from_function(py_func, py_file)

        def get_source_stamp(self) -> Any:
            return (super().get_source_stamp(), _package_stamp())

    PackageLocator.__name__ = PackageLocator.__qualname__ = f"Orca{base.__name__}"
    return PackageLocator


def _install() -> None:
    """Put the package's locators first (the user's cache directory, then ``__pycache__``); once."""
    try:
        classes = cast(list[Any], _caching.CacheImpl._locator_classes)
        bases = (_caching.UserProvidedCacheLocator, _caching.InTreeCacheLocator)
    except AttributeError:  # another numba: its own per-file stamps apply
        return
    if any(getattr(c, "__name__", "").startswith("Orca") for c in classes):
        return
    classes[:0] = [_stamped(b) for b in bases]


_install()


def njit(fn: F) -> F:
    """``numba.njit(cache=True)`` with the package-wide cache stamp."""
    return cast(F, numba.njit(cache=True)(fn))
