"""A ranking and a characterisation of one's own, registered by entry point
(pyproject.toml): sdbc finds them by name when a treatment declares them."""

from own_parts.characterisation import FinalPosition, FinalPositionOptions
from own_parts.ranking import StochasticRanking, StochasticRankingOptions

__all__ = [
    "FinalPosition",
    "FinalPositionOptions",
    "StochasticRanking",
    "StochasticRankingOptions",
]
