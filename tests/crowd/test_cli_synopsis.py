"""The synopses a newcomer reads (README's, and ``crowd/cli.py``'s docstring) list every option of every command,
and no option a command does not take (issue 48)."""
import argparse
import re

import pytest
from crowd_testutil import REPO

import crowd.cli as cli


def _parser_options() -> dict:
    """command -> its long options, as ``crowd COMMAND --help`` lists them (--help left out)."""
    p = cli.build_parser()
    sub = next(a for a in p._actions if isinstance(a, argparse._SubParsersAction))
    return {name: {o for act in sp._actions for o in act.option_strings if o.startswith("--") and o != "--help"}
            for name, sp in sub.choices.items()}


def _synopsis_options(text: str) -> dict:
    """command -> the long options its synopsis lines name: a line ``crowd COMMAND ...`` and the lines after it
    that continue it (indented, starting with ``[``); comments (``# ...``) left out."""
    out, cmd = {}, None
    for line in text.splitlines():
        body = line.split("#", 1)[0]
        m = re.match(r"\s*crowd (\w+)\b", body)
        if m:
            cmd = m.group(1)
            out.setdefault(cmd, set())
        elif not (cmd and body.strip().startswith("[")):
            cmd = None if body.strip() else cmd
            continue
        out[cmd] |= set(re.findall(r"(?<![\w-])--[a-z][a-z-]*", body))
    return out


def _readme_block() -> str:
    text = (REPO / "README.md").read_text(encoding="utf-8")
    blocks = re.findall(r"```sh\n(.*?)```", text, re.S)
    return next(b for b in blocks if "crowd report" in b and "crowd inspect" in b)


@pytest.mark.parametrize("where", ["README.md", "crowd/cli.py"])
def test_synopsis_lists_every_option_of_every_command(where):
    text = _readme_block() if where == "README.md" else cli.__doc__
    got, want = _synopsis_options(text), _parser_options()
    assert sorted(got) == sorted(want), f"{where}: commands {sorted(got)} vs --help {sorted(want)}"
    for cmd, opts in want.items():
        assert got[cmd] == opts, (f"{where}: crowd {cmd}: missing {sorted(opts - got[cmd])}, "
                                  f"not taken {sorted(got[cmd] - opts)}")


def test_the_synopsis_check_can_fail():
    text = "crowd run SCENE [--frames N]\n    [--bogus]\ncrowd fly SCENE  # --size in a comment\n"
    assert _synopsis_options(text) == {"run": {"--frames", "--bogus"}, "fly": set()}
