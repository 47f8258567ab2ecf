"""Command-line options that several commands share, spelt once: `--engines`.

Every command that takes engines takes them as `--engines A,B,…` (or `all`); `--engine`,
the spelling `run`, `report`, `gate`, `bless` and `bench` used before, is still read for
this release and says on stderr that it is now `--engines`.
"""

from __future__ import annotations

import argparse
import sys

#: what the old spelling prints, once per use
ALIAS_NOTE = "rsmcheck: --engine is now --engines (the old spelling is read for this release only)\n"


class _EngineAlias(argparse.Action):
    """`--engine X`: stored as `--engines X`, with ALIAS_NOTE on stderr."""

    def __call__(self, parser, namespace, values, option_string=None):
        sys.stderr.write(ALIAS_NOTE)
        setattr(namespace, self.dest, values)


def engines_option(parser: argparse.ArgumentParser, help: str, default: str | None = None) -> None:
    """`--engines A,B` (dest `engines`) on `parser`, and the hidden alias `--engine`."""
    parser.add_argument("--engines", metavar="A,B", default=default, help=help)
    parser.add_argument("--engine", dest="engines", action=_EngineAlias, help=argparse.SUPPRESS)
