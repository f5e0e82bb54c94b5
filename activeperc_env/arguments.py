"""The argument parser of every console script: errors in one line."""

from __future__ import annotations

import argparse


class ArgumentParser(argparse.ArgumentParser):
    """argparse's parser whose errors are one line, as every other error of the console scripts (argparse prints the
    usage of every flag first; that is what ``--help`` is for)."""

    def error(self, message: str):
        """Print ``PROG: error: MESSAGE`` and a pointer to ``--help``, and exit with status 2."""
        self.exit(2, f"{self.prog}: error: {message} (see {self.prog} --help)\n")
