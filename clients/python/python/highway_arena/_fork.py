"""Connections in a process made by ``fork()``. Zenoh's runtime threads stay in the
process that started them: a child forked from a process that had connected inherits
that runtime's state without its threads, and the extension refuses to connect there
(code ``Forked``) rather than wait for ever. Such a child connects through a fresh copy
of the extension instead, loaded from a copy of its file (a library loaded from another
file has statics of its own, so Zenoh starts anew in the child). Where a copy cannot be
loaded, the child gets the extension's error, which says to use the ``spawn`` start
method."""

from __future__ import annotations

import importlib.util
import os
import shutil
import tempfile

from . import _core

_active = _core
# The ArenaError class of every copy of the extension loaded in this process (each copy
# has its own): what ``except`` and ``isinstance`` check against.
errors: tuple[type, ...] = (_core.ArenaError,)


def extension():
    """The extension this process connects with: the one imported, unless Zenoh was
    started in it by a process this one was forked from; then a fresh copy."""
    global _active, errors
    if _active.forked():
        try:
            _active = _fresh_copy()
        except (ImportError, OSError):
            return _active  # its Client raises the Forked error with its advice
        errors = (*errors, _active.ArenaError)
    return _active


def _fresh_copy():
    original = _core.__file__
    folder = tempfile.mkdtemp(prefix=f"highway-arena-{os.getpid()}-")
    try:
        path = os.path.join(folder, os.path.basename(original))
        shutil.copyfile(original, path)
        # The module name keeps the init function's (PyInit__core); the other file makes
        # it another library. Loaded, the file is no longer needed.
        spec = importlib.util.spec_from_file_location(_core.__name__, path)
        module = importlib.util.module_from_spec(spec)
        spec.loader.exec_module(module)
        return module
    finally:
        shutil.rmtree(folder, ignore_errors=True)
