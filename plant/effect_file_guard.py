"""Importing a user's effect file without letting it end or hijack the command (issue 33).

An effect file is the user's code, run at import. Whatever it does there that is not defining an effect must end
as one clear error naming the file, never as the command's own end: ``sys.exit()`` (``SystemExit``), a
``KeyboardInterrupt`` or any other ``BaseException`` it raises, and text printed to standard output (which carries
a command's results and its ``--json`` document). A real Ctrl-C during the import is still a Ctrl-C: a temporary
SIGINT handler tells the user's interrupt from one the file raises itself (main thread only; elsewhere a raised
``KeyboardInterrupt`` is taken as the user's).
"""

from __future__ import annotations

import contextlib
import io
import signal
import threading
from collections.abc import Callable
from types import FrameType

from board_config.errors import InputError

#: printed text quoted in the error, at most this many characters
QUOTE_CHARS = 60


def _what_ended(exc: BaseException) -> str:
    if isinstance(exc, SystemExit):
        return f"called sys.exit({exc.code!r})" if exc.code is not None else "called sys.exit()"
    return f"raised {type(exc).__name__}" + (f": {exc}" if str(exc) else "")


def guarded_import(run: Callable[[], object], label: str, error: type[InputError]) -> None:
    """Run ``run`` (a module's ``exec_module``) as the import of the effect file ``label``: an ``Exception``,
    ``SystemExit`` or other ``BaseException`` it raises, and any text it prints to stdout, become ``error`` naming
    the file; a real SIGINT during it is re-raised as ``KeyboardInterrupt``."""
    sigint = {"real": False}
    previous: object = None
    main = threading.current_thread() is threading.main_thread()
    if main:
        def on_sigint(signum: int, frame: FrameType | None) -> None:
            sigint["real"] = True
            raise KeyboardInterrupt

        try:
            previous = signal.signal(signal.SIGINT, on_sigint)
        except (ValueError, OSError):
            main = False
    printed = io.StringIO()
    try:
        with contextlib.redirect_stdout(printed):
            run()
    except KeyboardInterrupt:
        if sigint["real"] or not main:
            raise
        raise error(f"effect file '{label}' raised KeyboardInterrupt while imported: an effect file must only define "
                    "its effect (no input(), no interrupts of its own)") from None
    except Exception as exc:
        raise error(f"cannot import effect file '{label}': {type(exc).__name__}: {exc}") from exc
    except BaseException as exc:  # SystemExit, GeneratorExit, a BaseException subclass of the user's
        raise error(f"effect file '{label}' {_what_ended(exc)} while imported: an effect file must only define its "
                    "effect class, not end the program") from None
    finally:
        if main:
            signal.signal(signal.SIGINT, previous)  # type: ignore[arg-type]
    text = printed.getvalue()
    if text:
        quote = " ".join(text.split())
        quote = quote if len(quote) <= QUOTE_CHARS else quote[:QUOTE_CHARS - 1] + "…"
        raise error(f"effect file '{label}' printed to standard output while imported ('{quote}'): standard output "
                    "carries the command's results (and its --json document); remove the print or write to "
                    "sys.stderr")
