"""``shm`` entry point. Each command group is one module exposing ``register(subparsers)``; adding a
command is one new module plus one line in :data:`COMMAND_MODULES`.

Exit codes: 0 success, 1 the job ran but reports a failure (e.g. a fault verdict where none was expected
is *not* an error; an integration failure is), 2 bad usage or bad input (with a message naming it).
"""

from __future__ import annotations

import argparse
import importlib
import sys
from collections.abc import Sequence

#: command modules, each with ``register(subparsers)``; the handler is set with ``set_defaults(func=...)``
COMMAND_MODULES: tuple[str, ...] = (
    "shm_cli.model_cmd",
    "shm_cli.campaign_cmd",
    "shm_cli.harvest_cmd",
    "shm_cli.hil_cmd",
    "shm_cli.run_cmd",
    "shm_cli.log_cmd",
    "shm_cli.synth_cmd",
    "shm_cli.compare_cmd",
    "shm_cli.diagnose_cmd",
    "shm_cli.fit_cmd",
    "shm_cli.calibrate_cmd",
)

EXIT_OK = 0
EXIT_FAILURE = 1
EXIT_USAGE = 2


class CliError(Exception):
    """A user-facing error: printed as ``shm: error: <message>`` with exit code 2."""


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="shm",
        description="mfc-shm: self-powered SHM board with MFC piezo patches — physics, firmware mock, "
                    "hardware links, model workbench.",
    )
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    sub.required = True
    for name in COMMAND_MODULES:
        importlib.import_module(name).register(sub)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    from board_config import ConfigError

    parser = build_parser()
    args = parser.parse_args(argv)
    try:
        return int(args.func(args) or 0)
    except (CliError, ConfigError) as exc:
        print(f"shm: error: {exc}", file=sys.stderr)
        return EXIT_USAGE
    except ValueError as exc:  # EffectError and input validation errors are ValueErrors with messages
        print(f"shm: error: {exc}", file=sys.stderr)
        return EXIT_USAGE
    except KeyboardInterrupt:
        print("shm: interrupted", file=sys.stderr)
        return 130


if __name__ == "__main__":
    sys.exit(main())
