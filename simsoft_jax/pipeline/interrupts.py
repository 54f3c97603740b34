"""Ctrl-C that is never lost.

Python turns SIGINT into a ``KeyboardInterrupt`` raised in whatever Python code the main
thread runs next. When that code is a garbage-collector callback (JAX registers one that
runs during its compiles) or an object's finalizer (``__del__``), Python prints
"Exception ignored in ..." and drops the exception: the command goes on compiling and
solving as if Ctrl-C had not been pressed (seen in 2 of 15 Ctrl-C's sent while
the static solver compiles). :func:`install` replaces Python's handler by one that raises
as Python does, except inside such a callback, where it sends the signal again a moment
later, once the callback has returned.
"""
from __future__ import annotations

import gc
import os
import signal
import threading

RETRY_S = 0.02   # the delay before a deferred SIGINT is sent again (s)


def in_dropping_context(frame) -> bool:
    """Whether an exception raised in ``frame`` (a Python frame, as a signal handler gets
    it) would be dropped by the interpreter: the frame or one it was called from is a
    garbage-collector callback or a ``__del__`` method."""
    callbacks = {getattr(cb, "__code__", None) for cb in gc.callbacks}
    while frame is not None:
        if frame.f_code in callbacks or frame.f_code.co_name == "__del__":
            return True
        frame = frame.f_back
    return False


def raise_or_defer(signum, frame) -> None:
    """SIGINT handler: ``KeyboardInterrupt`` as Python's own handler raises it, or, where
    the interpreter would drop it (:func:`in_dropping_context`), the same signal sent again
    after ``RETRY_S`` seconds from a daemon thread."""
    if in_dropping_context(frame):
        timer = threading.Timer(RETRY_S, os.kill, (os.getpid(), signum))
        timer.daemon = True
        timer.start()
        return
    raise KeyboardInterrupt


def install() -> None:
    """Use :func:`raise_or_defer` for SIGINT where Python's default handler is in place
    (not where SIGINT is ignored, as in a job a shell started in the background)."""
    if signal.getsignal(signal.SIGINT) is signal.default_int_handler:
        signal.signal(signal.SIGINT, raise_or_defer)
