"""Which checked claims are the paper's and which this project's own targets."""

from __future__ import annotations

from imply.results import Claim, claim_kind, claim_tally


def test_the_section5_per_seed_bar_counts_as_the_project_s_target_not_the_paper_s_claim():
    bar = Claim("s5-targets-seed0", "5", "own r >= 0.9 ...", False)
    claim = Claim("s5-own-tracks", "5", "tracks the object", True)
    assert claim_kind("section5", bar.id) == "project" and claim_kind("section5", claim.id) == "paper"
    assert claim_kind("gap", "gap-null") == "project"
    tally = claim_tally([("section5", bar), ("section5", claim), ("section5", {"id": "s5-targets-seed1", "holds": 1})])
    assert tally == {"paper": {"checked": 1, "hold": 1}, "project": {"checked": 2, "hold": 1}}
