"""Options used or refused: each given at most once, and none accepted where it has no effect.

Two classes of options would otherwise be accepted and do nothing:

* a repeated option (``--periods 10 --periods 20``): argparse keeps the last
  value.  Every single-valued option of the ``hammerbit`` parser is stored by
  :class:`StoreOnce` or :class:`StoreTrueOnce` (registered as its ``store``
  and ``store_true`` actions, :data:`ONCE`), which refuse a second
  occurrence (exit 2, naming both values).  Repeatable options
  (``--set``, ``--axis``) check their items for repeated names themselves.
* an option that only matters with another one (``--rtol`` with ``--method
  rk4``, ``optimize --fmu`` without ``--confirm``): the command refuses it
  with :func:`refuse_unless` before any work, naming the option, its value
  and why (exit 2).  :func:`given` tells an option typed on the command line
  from its default.
"""
from __future__ import annotations

import argparse

from hammerbit.cli.common import UsageError

__all__ = ["StoreOnce", "StoreTrueOnce", "ONCE", "command_options", "given", "refuse_unless", "refuse_repeated_names",
           "GIVEN_ATTR"]

#: The namespace attribute that holds ``{dest: (option as typed, value)}`` of the options given.
#: It lives in the namespace because argparse copies a sub-command's namespace into the caller's.
GIVEN_ATTR = "_options_given"


def _show(value) -> str:
    if value is None:
        return ""
    if isinstance(value, (list, tuple)):
        return " ".join(str(v) for v in value)
    return str(value)


def _note(action, parser, namespace, values, option_string) -> None:
    seen = getattr(namespace, GIVEN_ATTR, None)
    if seen is None:
        seen = {}
        setattr(namespace, GIVEN_ATTR, seen)
    if action.dest in seen:
        first, value = seen[action.dest]
        twice = f"{first} {_show(value)}".strip() + ", then " + f"{option_string} {_show(values)}".strip()
        parser.error(f"{option_string} given twice ({twice}): give it once")
    seen[action.dest] = (option_string, values)


class StoreOnce(argparse.Action):
    """``store``, refusing a second occurrence of the option."""

    def __call__(self, parser, namespace, values, option_string=None):
        _note(self, parser, namespace, values, option_string)
        setattr(namespace, self.dest, values)


class StoreTrueOnce(argparse.Action):
    """``store_true``, refusing a second occurrence of the flag."""

    def __init__(self, option_strings, dest, default=False, required=False, help=None):
        super().__init__(option_strings=option_strings, dest=dest, nargs=0, const=True, default=default,
                         required=required, help=help)

    def __call__(self, parser, namespace, values, option_string=None):
        _note(self, parser, namespace, None, option_string)
        setattr(namespace, self.dest, True)


#: argparse's action names and the once-only classes that replace them (:meth:`Parser.add_argument`).
ONCE = {None: StoreOnce, "store": StoreOnce, "store_true": StoreTrueOnce}


def given(args, dest: str) -> bool:
    """True if the option stored in ``dest`` was typed on the command line (not its default)."""
    return dest in (getattr(args, GIVEN_ATTR, None) or {})


def _typed(args, dest: str) -> str:
    """The option as typed, with its value: ``--rtol 1e-06``."""
    option, value = (getattr(args, GIVEN_ATTR, None) or {}).get(dest, ("--" + dest.replace("_", "-"), None))
    return option if value is None else f"{option} {_show(value)}"


def refuse_unless(args, dest: str, condition: bool, why: str) -> None:
    """Refuse the option of ``dest`` if it was given and ``condition`` is false (exit 2): the
    message names the option and its value as typed, then ``why``."""
    if given(args, dest) and not condition:
        raise UsageError(f"{_typed(args, dest)}: {why}")


def refuse_repeated_names(option: str, items, name_of) -> None:
    """Refuse two items of a repeatable option that set the same name (``--bounds a=.. a=..``)."""
    seen = {}
    for item in items or ():
        name = name_of(item)
        if name in seen:
            raise UsageError(f"{option} {item}: {name} is already given ({option} {seen[name]}); give each "
                             f"name once")
        seen[name] = item


def command_options(parser) -> dict:
    """``{"fmu build": [action, ...], ...}``: every command (nested ones by their full name) and its
    options, from argparse's own tables (``--help`` left out).

    argparse has no public API for walking a parser; this function is the one
    place that reads its tables (``tests/test_cli_options.py`` fails if they change).
    """
    out = {}

    def walk(p, prefix):
        subs = [a for a in p._actions if isinstance(a, argparse._SubParsersAction)]
        if prefix:
            out[" ".join(prefix)] = [a for a in p._actions if a.option_strings
                                     and not isinstance(a, argparse._HelpAction)]
        for s in subs:
            for name, child in s.choices.items():
                walk(child, prefix + [name])

    walk(parser, [])
    return out
