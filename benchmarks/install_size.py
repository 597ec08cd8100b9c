"""The size of what ``pip install`` brings: the core's requirements against another commit's, in one process.

Reads the ``dependencies`` of ``pyproject.toml`` here and at ``--before`` (a git revision; default 31af907, the last
commit before the core and the study were split), follows each requirement through the installed distributions'
own requirements (``importlib.metadata``, extras honoured) and sums the sizes their RECORD files list. Measured in
this environment, so a distribution's size is its installed build here (a CPU torch, for one).

Run: python benchmarks/install_size.py [--before REV]
Benchmarks measure; they assert nothing.
"""

from __future__ import annotations

import argparse
import importlib.metadata as md
import subprocess
import tomllib
from pathlib import Path

from packaging.requirements import Requirement

ROOT = Path(__file__).resolve().parents[1]


def closure(requirements: list[str]) -> dict[str, md.Distribution]:
    """Every installed distribution the requirements reach (missing ones are reported and skipped)."""
    seen: dict[str, md.Distribution] = {}
    stack = [Requirement(r) for r in requirements]
    while stack:
        req = stack.pop()
        name = req.name.lower().replace("_", "-")
        if name in seen:
            continue
        try:
            dist = md.distribution(req.name)
        except md.PackageNotFoundError:
            print(f"not installed here: {req.name}")
            continue
        seen[name] = dist
        for text in dist.requires or []:
            sub = Requirement(text)
            if sub.marker is None or any(sub.marker.evaluate({"extra": e}) for e in (req.extras or {""})):
                stack.append(sub)
    return seen


def megabytes(dist: md.Distribution) -> float:
    return sum(f.size or 0 for f in dist.files or []) / 1e6


def dependencies(text: str) -> list[str]:
    return tomllib.loads(text)["project"]["dependencies"]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--before", default="31af907", help="the git revision to compare with")
    args = ap.parse_args()
    before = subprocess.run(
        ["git", "show", f"{args.before}:pyproject.toml"], cwd=ROOT, capture_output=True, text=True, check=True
    ).stdout
    sizes = {}
    for label, reqs in (
        (args.before, dependencies(before)),
        ("here", dependencies((ROOT / "pyproject.toml").read_text())),
    ):
        dists = closure(reqs)
        sizes[label] = sum(megabytes(d) for d in dists.values())
        largest = sorted(dists, key=lambda n: -megabytes(dists[n]))[:6]
        print(
            f"{label}: {len(dists)} distributions, {sizes[label]:,.0f} MB; largest: "
            + ", ".join(f"{n} {megabytes(dists[n]):.0f}" for n in largest)
        )
    print(f"ratio here / {args.before}: {sizes['here'] / sizes[args.before]:.2f}")


if __name__ == "__main__":
    main()
