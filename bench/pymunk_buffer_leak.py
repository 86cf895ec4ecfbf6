"""Reproducer, with pymunk alone: ``pymunk.batch.Buffer`` never frees its C arrays.

pymunk 7.3.1's ``Buffer.__init__`` allocates two C arrays (``pmFloatArrayNew``,
``pmIntArrayNew``) and nothing frees them: the class has no ``__del__`` and the
arrays are not ``ffi.gc``-managed. Each round below makes a Space of ``--bodies``
bodies, reads them in bulk into a new Buffer (as a program does that makes a
Space per batch of work), and drops both. The process's resident memory grows by
the arrays' size every round, outside Python's heap (tracemalloc does not see it,
``malloc_trim`` cannot return it). ``--reuse`` keeps one Buffer for every round:
the growth stops.

Prints the resident set size every ``--every`` rounds after ``--warmup`` rounds,
and the growth per round and per body.

Run: ``.venv/bin/python bench/pymunk_buffer_leak.py [--reuse]`` (options:
``--rounds``, ``--bodies``, ``--every``, ``--warmup``).
"""

from __future__ import annotations

import argparse
import gc

import pymunk
import pymunk.batch as pb


def rss_bytes() -> int:
    """Resident set size of this process (Linux)."""
    with open("/proc/self/statm") as f:
        return int(f.read().split()[1]) * 4096


def one_round(bodies: int, buffer: pb.Buffer | None) -> None:
    space = pymunk.Space()
    for i in range(bodies):
        body = pymunk.Body(1.0, 1.0)
        body.position = (float(i), 0.0)
        space.add(body, pymunk.Circle(body, 0.5))
    space.step(0.01)
    data = buffer if buffer is not None else pb.Buffer()
    data.clear()
    fields = pb.BodyFields.BODY_ID | pb.BodyFields.POSITION | pb.BodyFields.VELOCITY
    pb.get_space_bodies(space, fields, data)
    assert len(data.float_buf()) == bodies * 4 * 8


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--rounds", type=int, default=2000)
    parser.add_argument("--bodies", type=int, default=200)
    parser.add_argument("--every", type=int, default=250)
    parser.add_argument("--warmup", type=int, default=200)
    parser.add_argument(
        "--reuse", action="store_true", help="one Buffer for every round"
    )
    args = parser.parse_args()
    shared = pb.Buffer() if args.reuse else None
    print(
        f"pymunk {pymunk.version}, {args.bodies} bodies per round, reuse={args.reuse}"
    )
    for _ in range(args.warmup):
        one_round(args.bodies, shared)
    gc.collect()
    start = rss_bytes()
    for r in range(1, args.rounds + 1):
        one_round(args.bodies, shared)
        if r % args.every == 0:
            gc.collect()
            print(f"round {r:6d}: RSS {rss_bytes() / 2**20:8.2f} MiB")
    grown = rss_bytes() - start
    print(
        f"growth: {grown / args.rounds:.1f} bytes per round, "
        f"{grown / args.rounds / args.bodies:.1f} per body"
    )


if __name__ == "__main__":
    main()
