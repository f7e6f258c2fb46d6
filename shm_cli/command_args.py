"""The argparse pieces several ``shm`` commands declare alike, written once: a command's parser with its summary and
description, the record inputs of the workbench commands (records, ``--scheduler``, ``--params``) and their
held-out split (``--holdout``, ``--blocks``, ``--max-rate-hz``)."""

from __future__ import annotations

import argparse

from shm_cli.batch_records import add_scheduler_arg
from shm_cli.common import add_params_arg, even_int


def add_command(sub: argparse._SubParsersAction, name: str, summary: str,
                description: str) -> argparse.ArgumentParser:
    """The parser of command ``name``: ``summary`` is its line in ``shm --help``, ``description`` the paragraph of
    ``shm NAME --help``, written as a text block (its line breaks and indentation fold into single spaces, as argparse
    shows it anyway)."""
    parser: argparse.ArgumentParser = sub.add_parser(name, help=summary, description=" ".join(description.split()))
    return parser


def add_record_inputs(p: argparse.ArgumentParser, records_help: str) -> None:
    """The inputs of a command that reads measurement records: the record files (or a folder or 'glob': a batch,
    ``--scheduler``) and the parameter set (``--params``)."""
    p.add_argument("records", nargs="+", metavar="RECORD", help=records_help)
    add_scheduler_arg(p)
    add_params_arg(p)


def add_holdout_args(p: argparse.ArgumentParser, rate_use: str = "") -> None:
    """The held-out split of a fitting command (``--holdout``, ``--blocks``) and its sub-sampling (``--max-rate-hz``;
    ``rate_use`` says what the sub-sampled records are for, e.g. ``" for fitting"``)."""
    p.add_argument("--holdout", choices=("blocks", "records"), default="blocks",
                   help="held-out data: alternate blocks of every record (default) or every second record")
    p.add_argument("--blocks", type=even_int(2), default=10,
                   help="blocks per record for --holdout blocks (even, default 10)")
    p.add_argument("--max-rate-hz", type=float, default=250.0,
                   help=f"sub-sample records to at most this rate{rate_use} (default 250 Hz)")


def add_command_group(sub: argparse._SubParsersAction, name: str, summary: str,
                      description: str) -> argparse._SubParsersAction:
    """A command with sub-commands (``shm NAME SUBCOMMAND``, one of them required): the parser of ``name`` as
    :func:`add_command` makes it, and the action its sub-commands are added to (their choice in ``NAME_command``)."""
    group = add_command(sub, name, summary, description).add_subparsers(dest=f"{name}_command", metavar="SUBCOMMAND")
    group.required = True
    return group
