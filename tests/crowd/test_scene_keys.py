"""docs/scenes.md documents every key of every section and effect (issue 48, item 1): the page's generated section is
what ``crowd/scene_keys.py`` makes of the schemas, and each section's keys are exactly those the parser accepts there
(read from the parser's own unknown-key message, so a schema the page does not gather fails here)."""
import re

import pytest
from crowd_testutil import tiny_scene

from crowd.errors import SceneError
from crowd.scene import load_scene
from crowd.scene_keys import BEGIN, END, markdown, page_path, replace_section, sections


def _documented() -> dict:
    """section title -> the keys the page's tables list."""
    text = page_path().read_text(encoding="utf-8")
    body = text.split(BEGIN, 1)[1].split(END, 1)[0]
    out, title = {}, None
    for line in body.splitlines():
        m = re.match(r"### `(.*)`$", line)
        if m:
            title = m.group(1)
            out[title] = []
        m = re.match(r"\| `([^`]+)` \|", line)
        if m and title is not None:
            out[title].append(m.group(1))
    return out


def test_the_page_is_what_the_schemas_give():
    text = page_path().read_text(encoding="utf-8")
    assert BEGIN in text and END in text
    assert replace_section(text, markdown()) == text, "docs/scenes.md is stale: run `python -m crowd.scene_keys`"


def test_issue_48s_effect_keys_are_documented():
    doc = _documented()
    keys = {k for t, ks in doc.items() if t.startswith("[[effects]]") for k in ks}
    for k in ("assign", "cruise_speed", "heading_smoothing", "max_accel", "max_turn_rate", "run_clip",
              "run_hysteresis", "separation_radius", "w_alignment", "w_cohesion", "w_cruise", "w_separation",
              "walk_clip", "bounds_margin", "lookahead", "w_slide", "strength"):
        assert k in keys, k


def _accepted(write_scene, text: str) -> set:
    """The keys the parser lists as accepted when ``text`` (a scene with one bogus key) is loaded."""
    with pytest.raises(SceneError) as e:
        load_scene(write_scene(text))
    msg = str(e.value)
    assert "unknown key; accepted: " in msg, msg
    got = {k.strip() for k in msg.split("unknown key; accepted: ", 1)[1].split(",")}
    return set() if got == {"none"} else got  # a table with no keys (effect instancing)


def _with(section_text: str, **replace) -> str:
    return tiny_scene(replace=replace or None, append=section_text)


CASES = {
    "top level": lambda: "bogus_key = 1\n" + tiny_scene(),
    "[[characters]]": lambda: tiny_scene(replace={'name = "walker"': 'name = "walker"\nbogus_key = 1'}),
    "[[characters]] variation = {...}": lambda: tiny_scene(
        replace={'name = "walker"': 'name = "walker"\nvariation = { bogus_key = 1 }'}),
    '[[placement]] kind = "grid"': lambda: tiny_scene(replace={"rows = 2": "rows = 2\nbogus_key = 1"}),
    "[camera]": lambda: tiny_scene(replace={"[camera]": "[camera]\nbogus_key = 1"}),
    "[render]": lambda: tiny_scene(replace={"[render]": "[render]\nbogus_key = 1"}),
    "[output]": lambda: tiny_scene(append="\n[output]\nbogus_key = 1\n"),
    "[terrain]": lambda: tiny_scene(append="\n[terrain]\nbogus_key = 1\n"),
}


@pytest.mark.parametrize("title", sorted(CASES))
def test_each_section_documents_what_the_parser_accepts(write_scene, title):
    doc = _documented()
    got = _accepted(write_scene, CASES[title]())
    if title.startswith("[[placement]]"):  # the parser names the keys every kind has among the accepted ones
        got -= set(doc["[[placement]] (every kind)"])
    assert set(doc[title]) == got, f"{title}: page only {sorted(set(doc[title]) - got)}, parser only " \
                                   f"{sorted(got - set(doc[title]))}"


def test_every_effect_and_placement_kind_and_lod_mode_documents_what_the_parser_accepts(write_scene):
    from lod.modes import mode_names
    from sim.placement import PLACEMENTS
    from sim.systems import EFFECTS

    doc = _documented()
    for name in EFFECTS:
        text = tiny_scene(effects=f'[{{ name = "{name}", bogus_key = 1 }}]')
        assert set(doc[f'[[effects]] name = "{name}"']) == _accepted(write_scene, text), name
    common = set(doc["[[placement]] (every kind)"])
    for kind in PLACEMENTS:
        text = tiny_scene(append=f'\n[[placement]]\nkind = "{kind}"\ncharacter = "walker"\nbogus_key = 1\n')
        assert set(doc[f'[[placement]] kind = "{kind}"']) | common == _accepted(write_scene, text), kind
    every = set(doc["[lod] (every mode)"]) - {"mode"}
    for m in mode_names():
        text = tiny_scene(replace={'mode = "none"': f'mode = "{m}"\nbogus_key = 1'})
        assert set(doc[f'[lod] mode = "{m}"']) == _accepted(write_scene, text) - every, m


def test_every_section_the_schemas_give_is_on_the_page():
    doc = _documented()
    assert [t for t, _ in sections()] == list(doc)
    assert all(doc[t] == list(s) for t, s in sections())
