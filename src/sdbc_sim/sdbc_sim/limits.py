"""Every limit on what enters a run, in one place (docs/limits.md explains each).

A value beyond one of these is refused with one line naming the limit and the
value, before a run directory exists. They sit far above anything the paper's
study or a sensible experiment asks for; they exist so that a mistake or a
hostile file costs a message, not the machine's memory.

:func:`excerpt` is how a refusal echoes what it got: a short, bounded rendering,
however large or deeply nested the value (an alias bomb's repr would otherwise
be gigabytes).
"""

from __future__ import annotations

import reprlib
from typing import Any

CONFIG_FILE_BYTES = 1 << 20
"""Largest configuration file read (an experiment configuration, a treatment, a
study preset, a graph file, a digest): 1 MiB. The paper's largest is under 2 kB."""
CONFIG_DEPTH = 32
"""Deepest nesting of mappings and lists in a configuration, counted through
aliases (the paper's deepest is 4)."""
CONFIG_NODES = 100_000
"""Most values (scalars, lists, mappings) a configuration may hold once its YAML
aliases are expanded: what stops an alias bomb."""
CONFIG_ALIASES = 1_000
"""Most YAML aliases (``*name``) in one configuration."""
EXCERPT_CHARS = 80
"""Longest echo of a refused value in an error message."""
MAX_STEPS = 10_000_000
"""Most steps of one trial (``task_config.max_steps``): the paper's tasks take
300 to 1500; the engine keeps a few arrays of this length per batch."""
MAX_WORKERS = 256
"""Most local worker processes (``--workers``); each costs tens of MB, and the
memory check counts them."""
WORKER_BYTES = 200 * 1024 * 1024
"""Memory of one local worker process besides its trials (the interpreter,
numpy, pymunk, the task): 190 MB RSS measured in a forkserver worker after a
gate escape trial, rounded up."""
STATE_COUNT_STATES = 8192
"""Most dimensions of the ``state_count`` characterisation (``max_states``): its
counts are trials x states float64, about 130 MB for the paper's 2000 trials of
a generation at this limit (``levels: 3`` on foraging asks for 3^16 = 43
million)."""
MAX_CONNECT_TIMEOUT = 86_400.0
"""Longest ``--connect-timeout``, seconds (a day): beyond it, waits overflow."""

_REPR = reprlib.Repr()
_REPR.maxlevel = 3
_REPR.maxstring = 60
_REPR.maxother = 60
_REPR.maxlong = 40
_REPR.maxtuple = _REPR.maxlist = _REPR.maxarray = _REPR.maxdict = 6
_REPR.maxset = _REPR.maxfrozenset = _REPR.maxdeque = 6


def excerpt(value: Any, limit: int = EXCERPT_CHARS) -> str:
    """``repr(value)`` cut to at most ``limit`` characters, in time and memory
    bounded whatever ``value`` holds (nested containers are cut at 3 levels and 6
    items, as :mod:`reprlib` does)."""
    text = _REPR.repr(value)
    if len(text) <= limit:
        return text
    return text[: limit - 3] + "..."
