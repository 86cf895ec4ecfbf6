"""The one registry pattern: parts of an installed distribution's entry points are
named like the package's own, loaded only when named, never take over a package
name, and a broken one is reported in one line naming its entry point."""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pytest
from sdbc_evolution.ga.rankings import RANKINGS, RankingContext, parse_ranking
from sdbc_evolution.ga.treatments import parse_treatment
from sdbc_sim.parts import PartError, Registry
from sdbc_sim.settings import SettingsError, settings

MODULE = '''\
"""Rankings of one's own."""

import numpy as np
from sdbc_evolution.ga.rankings import Ranking
from sdbc_sim.settings import settings

LOADED = []


@settings
class ReversedOptions:
    """Options of the reversed ranking."""

    offset: int = 0
    """Rotates the order by this many places."""


class Reversed(Ranking):
    """Novelty reversed: the least novel first."""

    options_class = ReversedOptions

    def rank(self, context):
        order = np.argsort(context.given("novelty", "reversed"), kind="stable")
        return np.roll(order, self.options.offset), np.zeros(context.size, np.int64)


def not_a_ranking():
    """A function, not a part."""


LOADED.append(True)
'''
ENTRY_POINTS = {
    "reversed": "own_rankings:Reversed",
    "nsga2": "own_rankings:Reversed",  # a package name: never taken over
    "broken": "no_such_module_xyz:Ranking",
    "function": "own_rankings:not_a_ranking",
}


@pytest.fixture
def installed(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Iterator[None]:
    """A distribution as pip writes it, registering rankings of its own."""
    site = tmp_path / "site"
    site.mkdir()
    (site / "own_rankings.py").write_text(MODULE)
    info = site / "own_rankings-1.0.dist-info"
    info.mkdir()
    (info / "METADATA").write_text(
        "Metadata-Version: 2.1\nName: own-rankings\nVersion: 1.0\n"
    )
    lines = "".join(f"{name} = {value}\n" for name, value in ENTRY_POINTS.items())
    (info / "entry_points.txt").write_text(f"[{RANKINGS.group}]\n{lines}")
    monkeypatch.syspath_prepend(str(site))
    monkeypatch.delitem(__import__("sys").modules, "own_rankings", raising=False)
    RANKINGS.refresh()
    yield
    RANKINGS.refresh()


def context() -> RankingContext:
    return RankingContext(
        fitness=np.array([0.1, 0.5, 0.3]),
        novelty=np.array([2.0, 1.0, 3.0]),
        population=None,
        archive=None,
        archive_fitness=None,
        k=2,
        tie_break="crowding",
        rng=np.random.default_rng(0),
    )


def test_an_entry_point_part_is_declared_like_the_packages_own(installed) -> None:
    assert {"reversed", "broken", "function"} <= set(RANKINGS.names())
    spec = parse_ranking({"reversed": {"offset": 1}})
    assert spec.to_plain() == {"reversed": {"offset": 1}}
    assert spec.rank(context()).order.tolist() == [2, 1, 0]  # [1, 0, 2] rolled by 1
    treatment = parse_treatment(
        {"name": "mine", "characterisation": "sdbc", "ranking": "reversed"}
    )
    assert treatment.ranking.name == "reversed"
    assert parse_treatment(treatment.to_plain()) == treatment
    assert RANKINGS["nsga2"].part.__module__ == "sdbc_evolution.ga.rankings"


def test_entry_points_load_only_when_named(installed) -> None:
    import sys

    parse_ranking("nsga2")
    assert "own_rankings" not in sys.modules
    parse_ranking("reversed")
    assert sys.modules["own_rankings"].LOADED == [True]


def test_a_broken_entry_point_is_reported_in_one_line_naming_it(installed) -> None:
    with pytest.raises(SettingsError) as caught:
        parse_ranking("broken")
    message = str(caught.value)
    assert message == (
        "ranking: entry point broken = 'no_such_module_xyz:Ranking' of group "
        "'sdbc.rankings' does not load: ModuleNotFoundError: No module named "
        "'no_such_module_xyz'"
    )
    with pytest.raises(SettingsError, match=r"ranking: entry point function .* is "):
        parse_ranking("function")
    assert parse_ranking("reversed").name == "reversed"  # the others still load
    with pytest.raises(PartError, match="entry point broken"):
        list(RANKINGS.all())


def test_a_part_must_name_settings_with_a_default_for_every_option() -> None:
    class Base:
        options_class: type = object

    registry: Registry[Base] = Registry("widget", "sdbc.widgets", Base)

    class NoSettings(Base):
        options_class = dict

    with pytest.raises(PartError, match="must be a settings class"):
        registry.register("plain", NoSettings)

    @settings
    class Required:
        """An option with no default."""

        size: int

    class NoDefault(Base):
        options_class = Required

    with pytest.raises(PartError, match="needs a default for every option"):
        registry.register("required", NoDefault)

    @settings
    class Fine:
        """Every option defaulted."""

        size: int = 1

    class Good(Base):
        options_class = Fine

    registry.register("good", Good)
    registry.register("good", Good)  # the same again: nothing

    class Other(Base):
        options_class = Fine

    with pytest.raises(PartError, match="'good' is registered twice"):
        registry.register("good", Other)
    with pytest.raises(PartError, match="is not a subclass of"):
        registry.register("other", dict)  # type: ignore[arg-type]
    assert registry.names() == ("good",)
