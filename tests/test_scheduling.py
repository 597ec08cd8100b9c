"""The test workers' order (tests/scheduling.py): long modules first and spread, every test kept, long modules whole."""

from __future__ import annotations

from types import SimpleNamespace

import pytest

from scheduling import deal, share_sizes


class FakeItem:
    """What :func:`scheduling.deal` reads of a pytest item: its module's name and its ``duration`` marker."""

    def __init__(self, module: str, index: int, seconds: float | None) -> None:
        self.module = SimpleNamespace(__name__=module)
        self.name = f"{module}::{index}"
        self.marker = None if seconds is None else pytest.mark.duration(seconds).mark

    def get_closest_marker(self, name: str):
        return self.marker if name == "duration" else None


def collection(spec: list[tuple[str, int, float | None]]) -> list[FakeItem]:
    return [FakeItem(module, i, seconds) for module, n, seconds in spec for i in range(n)]


SPEC = [
    ("quick_a", 30, None),
    ("long_100", 1, 100),
    ("quick_b", 25, None),
    ("long_60", 3, 60),
    ("long_50", 2, 50),
    ("quick_c", 40, None),
    ("long_30", 1, 30),
]


def test_share_sizes_are_the_ones_worksteal_hands_out():
    assert share_sizes(102, 2) == [51, 51] and share_sizes(101, 2) == [50, 51] and share_sizes(10, 3) == [3, 3, 4]


def test_each_share_starts_with_its_long_modules_and_their_time_is_balanced():
    items = collection(SPEC)
    order = deal(list(items), 2)
    assert sorted(i.name for i in order) == sorted(i.name for i in items)
    first, second = order[:51], order[51:]
    # longest first to the emptier share: 100 | 60, then 50 to the 60 side, then 30 to the 100 side
    assert [i.module.__name__ for i in first[:2]] == ["long_100", "long_30"]
    assert {i.module.__name__ for i in second[:5]} == {"long_60", "long_50"}
    for share in (first, second):
        names = [i.module.__name__ for i in share]
        firsts = [k for k, n in enumerate(names) if n.startswith("quick")]
        assert not firsts or all(not n.startswith("long") for n in names[firsts[0] :])  # quick ones after the long
    # a long module's tests stay together (its module-scoped fixtures are built once); every module keeps its order
    names = [i.name for i in order]
    for module, n, seconds in SPEC:
        at = [names.index(f"{module}::{k}") for k in range(n)]
        assert at == sorted(at)
        if seconds is not None:
            assert at == list(range(at[0], at[0] + n))


def test_one_worker_keeps_the_collection_order():
    items = collection(SPEC)
    assert deal(list(items), 1) == items
