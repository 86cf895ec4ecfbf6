"""Configuration files cannot exhaust memory or the stack, nor hide a key: every
YAML file comes through one loader (sdbc_sim.yaml_input) with the limits of
sdbc_sim.limits, and every refusal echoes its value as a short excerpt."""

from __future__ import annotations

import dataclasses
import re
import tracemalloc
from pathlib import Path

import pytest
from sdbc_evolution.run.config import (
    ConfigError,
    config_from_dict,
    load_config,
    load_treatment,
)
from sdbc_evolution.study.presets import PresetError, load_preset_file
from sdbc_sim.limits import CONFIG_FILE_BYTES, EXCERPT_CHARS, excerpt
from sdbc_sim.settings import SettingsError
from sdbc_sim.task_state_msgs import LIMITS, TaskStateLimits
from sdbc_sim.yaml_input import YamlRefused, parse_yaml

ROOT = Path(__file__).resolve().parent.parent


def alias_bomb(levels: int = 9, width: int = 9, key: str = "treatment") -> str:
    """The "billion laughs": ``width ** levels`` strings in a few hundred bytes."""
    lines = [f"{key}:", f"  l0: &l0 [{', '.join(['lol'] * width)}]"]
    for level in range(1, levels):
        refs = ", ".join([f"*l{level - 1}"] * width)
        lines.append(f"  l{level}: &l{level} [{refs}]")
    return "\n".join(lines) + "\n"


def test_the_614_byte_bomb_under_treatment_is_refused_without_growing_memory(
    tmp_path: Path,
) -> None:
    text = alias_bomb()
    text += "#" * (614 - len(text) - 1) + "\n"
    assert len(text.encode()) == 614
    path = tmp_path / "bomb.yaml"
    path.write_text("task: gate_escape\n" + text)
    tracemalloc.start()
    try:
        with pytest.raises(ConfigError) as refused:
            load_config(path)
        _, peak = tracemalloc.get_traced_memory()
    finally:
        tracemalloc.stop()
    message = str(refused.value)
    assert "CONFIG_NODES" in message and str(path) in message
    assert "\n" not in message and len(message) < 300
    assert peak < 20 * 2**20, f"{peak / 2**20:.0f} MB to refuse 614 bytes"


def test_a_study_preset_and_a_treatment_file_bomb_are_refused_too(
    tmp_path: Path,
) -> None:
    preset = tmp_path / "preset.yaml"
    preset.write_text(alias_bomb(levels=7, key="tasks"))
    with pytest.raises(PresetError, match="CONFIG_NODES"):
        load_preset_file(preset)
    treatment = tmp_path / "t.yaml"
    treatment.write_text(alias_bomb(levels=7))
    with pytest.raises(ConfigError, match="CONFIG_NODES"):
        load_treatment(str(treatment))


def test_a_refusal_of_a_huge_shared_value_is_one_short_line() -> None:
    # What a bomb becomes once loaded: nine levels of one shared list.
    value: list[object] = ["lol"] * 9
    for _ in range(8):
        value = [value] * 9
    assert len(excerpt(value)) <= EXCERPT_CHARS
    with pytest.raises(SettingsError) as refused:
        config_from_dict({"ga": {"population_size": value}})
    message = str(refused.value)
    assert "ga.population_size" in message and len(message) < 300


def test_nesting_deeper_than_the_limit_is_one_line(tmp_path: Path) -> None:
    path = tmp_path / "nested.yaml"
    path.write_text("task_config: {x: " + "[" * 500 + "]" * 500 + "}\n")
    assert path.stat().st_size < 1100
    with pytest.raises(ConfigError, match=r"CONFIG_DEPTH\) at line 1") as refused:
        load_config(path)
    assert len(str(refused.value)) < 300


def test_nesting_through_aliases_counts_too() -> None:
    levels = ["a0: &a0 [[[[[[[[1]]]]]]]]"]
    levels += [f"a{i}: &a{i} [[[[[[[[*a{i - 1}]]]]]]]]" for i in range(1, 6)]
    with pytest.raises(YamlRefused, match="once its aliases are expanded"):
        parse_yaml("\n".join(levels), "x")


def test_an_alias_inside_its_own_anchor_is_refused() -> None:
    with pytest.raises(YamlRefused, match="inside its own anchor"):
        parse_yaml("a: &a [1, *a]\n", "x")


def test_a_file_above_the_size_limit_is_refused_before_it_is_parsed(
    tmp_path: Path,
) -> None:
    path = tmp_path / "big.yaml"
    path.write_text("task: gate_escape\n#" + "x" * CONFIG_FILE_BYTES + "\n")
    with pytest.raises(ConfigError, match="CONFIG_FILE_BYTES=1048576") as refused:
        load_config(path)
    assert str(path) in str(refused.value)


def test_a_duplicate_key_is_refused_naming_the_key_and_line(tmp_path: Path) -> None:
    path = tmp_path / "twice.yaml"
    path.write_text(
        "task: gate_escape\nga:\n  population_size: 10\n  population_size: 20\n"
    )
    with pytest.raises(ConfigError) as refused:
        load_config(path)
    message = str(refused.value)
    assert "'population_size' given twice" in message and "line 4" in message


def test_a_merge_key_may_still_be_overridden() -> None:
    data = parse_yaml("base: &b {k: 1, j: 2}\nuse:\n  <<: *b\n  k: 3\n", "x")
    assert data["use"] == {"k": 3, "j": 2}


def test_a_non_utf8_configuration_names_the_file(tmp_path: Path) -> None:
    path = tmp_path / "latin1.yaml"
    path.write_bytes("task: gate_escape\n# d\xe9j\xe0\n".encode("latin-1"))
    with pytest.raises(ConfigError, match=re.escape(f"{path} is not UTF-8")):
        load_config(path)


def test_a_huge_integer_is_refused_as_a_line() -> None:
    with pytest.raises(YamlRefused, match="ValueError"):
        parse_yaml("seed: " + "9" * 5000, "x")


def test_every_got_in_the_sources_goes_through_the_excerpt_helper() -> None:
    # A refusal echoing a value with !r prints all of it: an alias bomb's
    # repr is gigabytes.
    offenders = []
    for path in (ROOT / "src").rglob("*.py"):
        for number, line in enumerate(path.read_text().splitlines(), 1):
            if re.search(r"got \{[^}]*!r\}", line):
                offenders.append(f"{path.relative_to(ROOT)}:{number}")
    assert not offenders, offenders


def test_no_yaml_is_loaded_but_through_the_one_loader() -> None:
    offenders = []
    for path in (ROOT / "src").rglob("*.py"):
        if path.name == "yaml_input.py":
            continue
        for number, line in enumerate(path.read_text().splitlines(), 1):
            if re.search(r"yaml\.(safe_)?load|yaml\.(Safe|C)?Loader", line):
                offenders.append(f"{path.relative_to(ROOT)}:{number}")
    assert not offenders, offenders


def test_the_limits_are_stated_in_docs_limits() -> None:
    import sdbc_sim.limits as limits

    text = (ROOT / "docs" / "limits.md").read_text()
    names = [n for n in vars(limits) if n.isupper() and not n.startswith("_")]
    missing = [n for n in names if n not in text]
    assert names and not missing, missing


def undocumented_message_limits(text: str, limits: TaskStateLimits) -> list[str]:
    """The fields of a ``TaskStateLimits`` that ``text`` (docs/limits.md) has no
    table row of, as ``| `limits.NAME` | VALUE |``, with the field's value."""
    return [
        f"limits.{field.name} = {getattr(limits, field.name)}"
        for field in dataclasses.fields(limits)
        if not re.search(
            rf"^\| `limits\.{field.name}` \| {getattr(limits, field.name)} \|",
            text,
            flags=re.MULTILINE,
        )
    ]


def test_the_message_limits_are_stated_in_docs_limits() -> None:
    text = (ROOT / "docs" / "limits.md").read_text()
    assert TaskStateLimits() == LIMITS  # the defaults are the limits in force
    assert undocumented_message_limits(text, LIMITS) == []
    # A limit added without its row, or a row left at an old value, is caught.
    more = dataclasses.make_dataclass(
        "More", [("bags", int, 7)], bases=(TaskStateLimits,), frozen=True
    )
    assert undocumented_message_limits(text, more()) == ["limits.bags = 7"]
    changed = dataclasses.replace(LIMITS, entities=LIMITS.entities + 1)
    assert undocumented_message_limits(text, changed) == [
        f"limits.entities = {LIMITS.entities + 1}"
    ]
