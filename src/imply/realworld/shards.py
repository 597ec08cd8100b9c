"""The benchmarks' generation in shards: which logs a shard writes, and the shards' labels and timings joined.

A benchmark's logs are drawn all at once (:func:`imply.realworld.cases.draw_cases`: every
log's draws, noise seed included, come from the design's seed and the log's place in the
draw, never from the logs simulated beside it), so a shard draws every log and simulates
only its own: shard ``k`` of ``n`` holds the logs whose index in the set is ``k`` modulo
``n``. Each shard writes its logs and its part of the labels (and of the lab's timing);
:func:`merge_labels` and :func:`merge_timing` join the parts into what one unsharded run
writes.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import TypeVar

T = TypeVar("T")


def check_shard(shard: int, shards: int) -> None:
    """ValueError unless ``0 <= shard < shards``."""
    if shards < 1 or not 0 <= shard < shards:
        raise ValueError(f"shard {shard} of {shards}: need 0 <= shard < shards")


def shard_cases(cases: Sequence[T], shard: int, shards: int) -> list[T]:
    """The logs of shard ``shard`` of ``shards``: those whose index in ``cases`` (the set's drawn logs, or their
    files, in order) is ``shard`` modulo ``shards``."""
    check_shard(shard, shards)
    return [case for k, case in enumerate(cases) if k % shards == shard]


def merge_labels(parts: Sequence[Mapping[str, dict]]) -> dict[str, dict]:
    """One labels document ({log id: label}) from the shards' parts; ValueError if a log is in two parts."""
    out: dict[str, dict] = {}
    for part in parts:
        twice = sorted(set(out) & set(part))
        if twice:
            raise ValueError(f"log(s) {', '.join(twice[:5])} in more than one part")
        out.update(part)
    return dict(sorted(out.items()))


def merge_timing(parts: Sequence[Mapping[str, Mapping[str, float]]]) -> dict[str, dict]:
    """Each engine's simulated pushes and seconds ({engine: {pushes, seconds, seconds_per_push}}) summed over the
    shards' parts, the time per push over the sum."""
    out: dict[str, dict] = {}
    for part in parts:
        for engine, t in part.items():
            total = out.setdefault(engine, {"pushes": 0, "seconds": 0.0})
            total["pushes"] += int(t["pushes"])
            total["seconds"] += float(t["seconds"])
    for total in out.values():
        total["seconds_per_push"] = total["seconds"] / max(total["pushes"], 1)
    return out
