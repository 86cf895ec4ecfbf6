"""The options of the SDBC: the paper's configuration by default, and the additions
of the authors' later code and of the paper's future work.

- ``aggregation``: ``mean+final`` (paper), ``mean``, ``final``, ``regression`` or
  ``{frames: N}`` (:mod:`.aggregation`);
- ``state_deviation``: per group, the standard deviation of each state attribute
  over the group's present entities (the authors' later code);
- ``relations``: the difference of same-named attributes between two groups (the
  paper's extension (i), inter-group relations);
- ``ignore_groups``: groups left out by name, with every feature that involves them.

Which per-step features the options yield is :func:`.features.behaviour_features`;
how they become dimensions is :mod:`.aggregation`.
"""

from __future__ import annotations

from sdbc_sim.settings import check, settings

MODES = ("mean+final", "mean", "final", "frames", "regression")
"""Aggregation modes; ``frames`` takes a window count."""


@settings
class SdbcOptions:
    """How the SDBC is made; the defaults are the paper's."""

    aggregation: str | dict[str, int] = "mean+final"
    """``mean+final``, ``mean``, ``final``, ``regression`` or ``{frames: N}``."""
    state_deviation: bool = False
    """Add each group's per-attribute standard deviation over its entities."""
    relations: bool = False
    """Add the difference of same-named attributes between two groups."""
    ignore_groups: tuple[str, ...] = ()
    """Groups left out, by name."""

    def __post_init__(self) -> None:
        aggregation = self.aggregation
        modes = [m for m in MODES if m != "frames"]
        if isinstance(aggregation, dict):
            check(
                set(aggregation) == {"frames"},
                "aggregation",
                f"{aggregation!r} must be one of {modes} or {{frames: N}}",
            )
            check(
                aggregation["frames"] >= 1,
                "aggregation.frames",
                f"{aggregation['frames']!r} must be an integer >= 1",
            )
        else:
            check(
                aggregation in modes,
                "aggregation",
                f"{aggregation!r} must be one of {modes} or {{frames: N}}",
            )
        check(
            len(set(self.ignore_groups)) == len(self.ignore_groups),
            "ignore_groups",
            f"{list(self.ignore_groups)} has duplicates",
        )

    @property
    def mode(self) -> str:
        """The aggregation mode's name."""
        return "frames" if isinstance(self.aggregation, dict) else self.aggregation

    @property
    def frames(self) -> int:
        """N of ``frames: N`` (0 for the other modes)."""
        return self.aggregation["frames"] if isinstance(self.aggregation, dict) else 0

    @property
    def is_paper(self) -> bool:
        """The paper's options."""
        return self == SdbcOptions()


PAPER = SdbcOptions()
"""The paper's configuration."""
