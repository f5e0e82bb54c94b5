"""Command-line parsing shared by every console script: one-line errors, and flags generated from a typed config."""

from __future__ import annotations

import argparse
import dataclasses
import math

from activeperc_env.config import field_docs, shown_default


class ArgumentParser(argparse.ArgumentParser):
    """argparse's parser whose errors are one line, as every other error of the console scripts (argparse prints the
    usage of every flag first; that is what ``--help`` is for)."""

    def error(self, message: str):
        """Print ``PROG: error: MESSAGE`` and a pointer to ``--help``, and exit with status 2."""
        self.exit(2, f"{self.prog}: error: {message} (see {self.prog} --help)\n")


def whole_number(text: str) -> int:
    """The argparse type of the int flags: an int from ``text``, also in exponent notation when its value is whole
    (``2e6``); else ``argparse.ArgumentTypeError`` saying so, which argparse prints after the flag's name."""
    try:
        return int(text)
    except ValueError:
        try:
            value = float(text)
        except ValueError:
            value = math.nan
        if not (math.isfinite(value) and value.is_integer()):
            raise argparse.ArgumentTypeError(f"{text!r} is not a whole number") from None
        return int(value)


PARSERS = {"int": whole_number, "float": float, "str": str}  # a field's type -> how a flag's text becomes it


def add_config_flags(group, cls, choices: dict | None = None, skip=()) -> None:
    """One flag per field of the config dataclass ``cls`` (``num_envs`` -> ``--num-envs``; booleans get
    ``--x/--no-x``, tuples take several values), documented by the field's docstring and default; the flags set
    only what is given (their default is ``argparse.SUPPRESS``). ``choices`` maps field names to their choices."""
    docs = field_docs(cls)
    for f in dataclasses.fields(cls):
        if f.name not in skip:
            add_field_flag(group, f, docs.get(f.name, ""), shown_default(cls, f, as_flag=True), choices)


def add_field_flag(group, f: dataclasses.Field, doc: str, default: str, choices: dict | None = None) -> None:
    """The flag of the config field ``f`` in ``group`` (see :func:`add_config_flags`): ``doc`` and ``default`` are
    what its help says."""
    flag = "--" + f.name.replace("_", "-")
    kwargs = {"dest": f.name, "default": argparse.SUPPRESS, "help": f"{doc} (default: {default})".replace("%", "%%")}
    kind = f.type.removesuffix(" | None")
    if kind == "bool":
        group.add_argument(flag, action=argparse.BooleanOptionalAction, **kwargs)
    elif kind.startswith("tuple["):
        group.add_argument(flag, type=PARSERS[kind[6:].split(",")[0]], nargs="+", metavar="N", **kwargs)
    else:
        group.add_argument(flag, type=PARSERS[kind], choices=(choices or {}).get(f.name), **kwargs)
