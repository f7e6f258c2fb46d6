"""``shm`` entry point. Each command group is one module exposing ``register(subparsers)``; adding a
command is one new module plus one line in :data:`COMMAND_MODULES`.

Exit codes — the policy, in one place (:func:`main`):

* **0** the command did its job (a FAULT verdict found by a run is a result, not an error).
* **2** bad usage or bad input the user can fix: argparse errors (one line, ``shm <cmd>: error: ...; see
  'shm <cmd> --help'``, no usage block: :class:`ShmArgumentParser`), and every :class:`board_config.InputError`
  (``ConfigError``, ``RecordError``, ``EffectError``, ``FitError``, ``CampaignError``, :class:`CliError` ...). The
  message (``shm: error: ...``) names the file, option or value and why. Code that validates user input raises a
  subclass of ``InputError``, never a bare ``ValueError``.
* **1** the job ran but failed: a command that reports its own failure (an integration that diverged, a campaign
  with unfinished batches, an artefact that could not be written — the command says which), an operating-system
  error (``OSError``: a full disk, a permission), or an unexpected exception, which is a bug in mfc-shm: one line
  saying so, with the command, the exception type and message, and how to see the traceback (``shm --debug ...``
  or ``SHM_DEBUG=1``).
* **130** interrupted (Ctrl-C).

``--debug`` is a top-level flag (``shm --debug campaign ...``; also accepted anywhere before a ``--``); with it, or
with the environment variable ``SHM_DEBUG=1``, an unexpected exception prints its full traceback.
"""

from __future__ import annotations

import argparse
import gc
import importlib
import os
import sys
import traceback
from collections.abc import Sequence
from typing import NoReturn

from board_config.errors import InputError

#: command modules, each with ``register(subparsers)``; the handler is set with ``set_defaults(func=...)``
COMMAND_MODULES: tuple[str, ...] = (
    "shm_cli.model_cmd",
    "shm_cli.campaign_cmd",
    "shm_cli.harvest_cmd",
    "shm_cli.hil_cmd",
    "shm_cli.run_cmd",
    "shm_cli.log_cmd",
    "shm_cli.synth_cmd",
    "shm_cli.effects_cmd",
    "shm_cli.health_cmd",
    "shm_cli.compare_cmd",
    "shm_cli.diagnose_cmd",
    "shm_cli.fit_cmd",
    "shm_cli.discover_cmd",
    "shm_cli.calibrate_cmd",
)

EXIT_OK = 0
EXIT_FAILURE = 1
EXIT_USAGE = 2
EXIT_INTERRUPTED = 130

#: environment variable that turns on tracebacks for unexpected errors (any value but "", "0")
DEBUG_ENV = "SHM_DEBUG"


class CliError(InputError):
    """A user-facing error: printed as ``shm: error: <message>`` with exit code 2."""


class ShmArgumentParser(argparse.ArgumentParser):
    """A parser whose usage errors are one line, ``shm <cmd>: error: <what>; see 'shm <cmd> --help'`` (exit 2),
    not argparse's usage block followed by the error; its sub-commands' parsers are of this class too (argparse
    gives a sub-parser its parent's class). An unrecognised option is named with the command it was given to."""

    def error(self, message: str) -> NoReturn:
        self.exit(EXIT_USAGE, f"{self.prog}: error: {_one_line(message)}; see '{self.prog} --help'\n")

    def parse_args(self, args: Sequence[str] | None = None,  # type: ignore[override]
                   namespace: argparse.Namespace | None = None) -> argparse.Namespace:
        parsed, extras = self.parse_known_args(args, namespace)
        if extras:  # said by the parser of the command they were given to (argparse: by the top-level 'shm')
            _command_parser(self, command_words(parsed).split()[1:]).error(
                f"unrecognized arguments: {' '.join(extras)}")
        return parsed


def _command_parser(parser: argparse.ArgumentParser, words: list[str]) -> argparse.ArgumentParser:
    """The (sub-)parser of the command ``words`` (``["model", "frf"]``) under ``parser``."""
    for word in words:
        action = next((a for a in parser._actions if isinstance(a, argparse._SubParsersAction)), None)
        if action is None or word not in action.choices:
            break
        parser = action.choices[word]
    return parser


def build_parser() -> argparse.ArgumentParser:
    parser = ShmArgumentParser(
        prog="shm",
        description="mfc-shm: self-powered SHM board with MFC piezo patches — physics, firmware mock, "
                    "hardware links, model workbench.",
        epilog="exit codes: 0 done, 1 the job failed (or a bug in mfc-shm), 2 bad usage or bad input.",
    )
    parser.add_argument("--debug", action="store_true",
                        help=f"print the full traceback of an unexpected error (also: {DEBUG_ENV}=1)")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    sub.required = True
    for name in COMMAND_MODULES:
        importlib.import_module(name).register(sub)
    from shm_cli.common import refuse_nonfinite_floats

    refuse_nonfinite_floats(parser)  # NaN / inf refused by every float option (exit 2, naming it)
    return parser


def command_words(args: argparse.Namespace) -> str:
    """``"shm model frf"``: the command being run, for messages."""
    words = ["shm", str(getattr(args, "command", "") or "")]
    for key, value in sorted(vars(args).items()):
        if key.endswith("_command") and value:
            words.append(str(value))
    return " ".join(w for w in words if w)


def _split_debug(argv: list[str]) -> tuple[list[str], bool]:
    """Remove ``--debug`` from anywhere before a ``--`` separator."""
    end = argv.index("--") if "--" in argv else len(argv)
    kept = [a for a in argv[:end] if a != "--debug"] + argv[end:]
    return kept, len(kept) != len(argv)


def _one_line(text: object) -> str:
    return " ".join(str(text).split())


def debug_enabled(flag: bool = False) -> bool:
    return flag or os.environ.get(DEBUG_ENV, "") not in ("", "0")


def report_bug(what: str, exc: BaseException, debug: bool) -> None:
    """The one line for an unexpected exception (plus the traceback when debugging)."""
    if debug:
        traceback.print_exception(exc, file=sys.stderr)
    how = "traceback above" if debug else f"rerun with 'shm --debug ...' or {DEBUG_ENV}=1 for the traceback"
    print(f"shm: internal error, a bug in mfc-shm: '{what}' failed with {type(exc).__name__}: "
          f"{_one_line(exc) or '(no message)'} — please report it ({how})", file=sys.stderr)


def main(argv: Sequence[str] | None = None) -> int:
    if argv is None:  # the shm command itself (not a call from Python): exit without the interpreter's last sweep
        try:
            return _main(None)
        finally:
            skip_final_collection()
    return _main(argv)


def skip_final_collection() -> None:
    """Leave the objects alive now out of the interpreter's final garbage collection at exit (``gc.freeze``): after
    a command that compiled or loaded plant kernels, that sweep over numba's and LLVM's object graph kept the shell
    waiting 1-3 s after the last line (issue 27.1). Files and databases are closed by the commands themselves."""
    for stream in (sys.stdout, sys.stderr):
        try:
            stream.flush()
        except (OSError, ValueError):  # a closed pipe or stream: the exit's own flush reports it as before
            pass
    gc.freeze()


def _main(argv: Sequence[str] | None) -> int:
    argv, debug_flag = _split_debug(list(sys.argv[1:] if argv is None else argv))
    parser = build_parser()
    try:
        args = parser.parse_args(argv)
    except SystemExit as exc:  # a usage error (argparse printed it): return its code; --help (0) still exits
        if exc.code in (0, None):
            raise
        return exc.code if isinstance(exc.code, int) else EXIT_USAGE
    debug = debug_enabled(debug_flag or args.debug)
    what = command_words(args)
    try:
        return int(args.func(args) or 0)
    except InputError as exc:
        print(f"shm: error: {_one_line(exc)}", file=sys.stderr)
        return EXIT_USAGE
    except KeyboardInterrupt:
        print("shm: interrupted", file=sys.stderr)
        return EXIT_INTERRUPTED
    except BrokenPipeError:  # `shm ... | head`: the reader went away; nothing left to say
        try:
            sys.stdout = open(os.devnull, "w")  # keeps the final flush quiet
        except OSError:
            pass
        return EXIT_FAILURE
    except OSError as exc:  # the file system or the network refused: the job failed, not the user's input
        if debug:
            traceback.print_exception(exc, file=sys.stderr)
        print(f"shm: error: '{what}' failed: {_one_line(exc)}", file=sys.stderr)
        return EXIT_FAILURE
    except Exception as exc:  # anything else is a bug in mfc-shm
        report_bug(what, exc, debug)
        return EXIT_FAILURE


if __name__ == "__main__":
    sys.exit(main())
