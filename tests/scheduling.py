"""The order the test workers take the modules in: the longest first, dealt so that the workers' shares are even.

pytest-xdist's ``worksteal`` scheduler gives each of its K workers a contiguous share of the
collection (the first ``N // K`` tests to the first, and so on) and, when one runs dry, moves half
of the busiest one's queue to it from that queue's end. A long module near the end of a share is
then the last thing running, on one core. :func:`deal` reorders the collection so that each share
starts with long modules (those marked ``pytest.mark.duration(seconds)``, dealt longest first to the
share with the least time so far), each long module whole (its module-scoped fixtures are built once),
and ends with the quick ones in collection order (one may straddle two shares). The workers collect the same tests and
reorder them the same way, as xdist requires.
"""

from __future__ import annotations

from collections.abc import Sequence

import pytest


def module_seconds(items: Sequence[pytest.Item]) -> dict[str, float]:
    """Each module's ``duration`` marker's seconds (its module-level ``pytestmark``), by module name; modules without
    one are absent."""
    out: dict[str, float] = {}
    for item in items:
        marker = item.get_closest_marker("duration")
        if marker is not None:
            out[item.module.__name__] = float(marker.args[0] if marker.args else marker.kwargs["seconds"])
    return out


def share_sizes(n: int, workers: int) -> list[int]:
    """How many of ``n`` tests worksteal hands each of ``workers`` workers at the start (each the remaining tests
    divided by the workers still without a share)."""
    sizes = []
    for i in range(workers):
        sizes.append(n // (workers - i))
        n -= sizes[-1]
    return sizes


def deal(items: list[pytest.Item], workers: int) -> list[pytest.Item]:
    """``items`` reordered for ``workers`` worksteal workers (module doc); unchanged for fewer than two."""
    if workers < 2:
        return items
    seconds = module_seconds(items)
    modules: dict[str, list[pytest.Item]] = {}
    for item in items:
        modules.setdefault(item.module.__name__, []).append(item)
    long = sorted((m for m in modules if m in seconds), key=lambda m: -seconds[m])
    shares: list[list[pytest.Item]] = [[] for _ in range(workers)]
    load = [0.0] * workers
    for name in long:
        k = min(range(workers), key=lambda i: (load[i], i))
        shares[k].extend(modules[name])
        load[k] += seconds[name]
    quick = [item for name, tests in modules.items() if name not in seconds for item in tests]
    start = 0
    for share, size in zip(shares, share_sizes(len(items), workers), strict=True):
        take = max(size - len(share), 0)
        share.extend(quick[start : start + take])
        start += take
    shares[-1].extend(quick[start:])
    return [item for share in shares for item in share]
