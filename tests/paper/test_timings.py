"""The last run's time per rule and its critical path, from Snakemake's benchmark files."""

from __future__ import annotations

import os

from imply.paper.timings import alone, by_rule, markdown, read_benchmarks

HEADER = "s\th:m:s\tmax_rss\tmax_vms\tmax_uss\tmax_pss\tio_in\tio_out\tmean_load\tcpu_time\n"


def _job(folder, rule, wildcards, seconds, end, cpu=None, rss=100.0):
    path = folder / rule / f"{wildcards}.tsv"
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(HEADER + f"{seconds}\t0:00:00\t{rss}\t0\t0\t0\t0\t0\t0\t{cpu if cpu is not None else seconds}\n")
    os.utime(path, (end, end))


def test_time_per_rule_and_the_jobs_the_run_waited_on(tmp_path):
    # a table (0-40 s), two shards beside each other (40-100, 40-70), then a benchmark that waited on both (100-110)
    _job(tmp_path, "table", "all", 40, 1000)
    _job(tmp_path, "gap_diagnose", "0", 60, 1060, rss=300)
    _job(tmp_path, "gap_diagnose", "1", 30, 1030)
    _job(tmp_path, "gap_benchmark", "all", 10, 1070.5)
    jobs = read_benchmarks(tmp_path)
    assert [j.name for j in jobs] == ["table", "gap_diagnose (1)", "gap_diagnose (0)", "gap_benchmark"]
    rules = {r.rule: r for r in by_rule(jobs)}
    assert (
        rules["gap_diagnose"].jobs == 2 and rules["gap_diagnose"].seconds == 90 and rules["gap_diagnose"].longest == 60
    )
    assert rules["gap_diagnose"].max_rss_mb == 300
    # the table ran alone (40 s), shard 0 alone after shard 1 ended (30 s), the benchmark alone (10 s)
    idle, solo = alone(jobs)
    assert abs(idle - 81.0) < 1e-6  # the 0.5 s with nothing running counts both cores
    assert solo == {"table": 40.0, "gap_diagnose (0)": 30.0, "gap_benchmark": 10.0}
    text = "\n".join(markdown(jobs))
    assert "span 1.8 min" in text and "| gap_diagnose | 2 | 90.0 | 60.0 | 90.0 | 300 |" in text
    assert "A core stood idle for 1.4 core-min" in text and "| table | 40.0 |" in text


def test_no_benchmarks_says_so(tmp_path):
    assert read_benchmarks(tmp_path / "none") == []
    assert "No per-rule benchmarks were found" in markdown([])[2]


def test_a_run_resumed_after_a_pause_counts_each_sitting_s_span(tmp_path):
    from imply.paper.timings import sittings, span_seconds

    # a first sitting of two jobs (0-100 s), then a day's pause, then a rerun of one stage (200 s)
    _job(tmp_path, "table", "all", 60, 1060)
    _job(tmp_path, "gap_tables", "all", 40, 1100)
    _job(tmp_path, "gap_diagnose", "0", 200, 1100 + 86400 + 200)
    jobs = read_benchmarks(tmp_path)
    assert [len(s) for s in sittings(jobs)] == [2, 1]
    assert span_seconds(jobs) == 100 + 200
    assert "in 2 sittings" in "\n".join(markdown(jobs))


def test_the_critical_path_follows_the_jobs_each_waited_on():
    from imply.paper.timings import Job, critical_path

    def job(rule, start, end):
        return Job(rule=rule, wildcards="all", seconds=end - start, cpu_seconds=end - start, max_rss_mb=1.0, end=end)

    # table -> clips -> train (long) -> merge; a side job beside train ends before it and is off the path
    jobs = [
        job("table", 0, 100),
        job("clips", 101, 300),
        job("side", 101, 500),
        job("train", 302, 1200),
        job("gap", 501, 900),
        job("merge", 1201, 1210),
    ]
    assert [j.rule for j in critical_path(jobs)] == ["table", "clips", "train", "merge"]
    assert critical_path([]) == []
