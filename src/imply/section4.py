"""The controlled validation (paper Section 4), as small steps the workflow runs one by one.

Steps and their files (all under ``results/section4/``; config key ``section4``):

1. :func:`draw_objects` -> ``objects.csv``: ``objects.n`` evaluation objects and
   ``objects.n_train`` training objects (population ``eval``/``train``). Mass and
   friction are log-uniform within ``objects.mass``/``objects.friction`` (which must lie
   in the table's range); each box half-extent is the scene's canonical one times
   exp(``objects.size_log_sd`` * z), so the oracle's residual against the
   canonical-box table is small but not zero.
2. :func:`simulate_truth` -> ``truth.csv``: every evaluation object pushed at the
   calibration speeds and the K query speeds (config ``score``), every training object
   at the query speeds, with true physics and geometry: one batched simulation.
3. :func:`make_standins` -> ``rollouts.csv``: the stand-ins' rollouts at the query
   speeds (see :mod:`imply.standins`); jitter has ``standins.jitter_draws`` independent
   rollout sets per object (draw 0 is the one scored in Table 1; the selection study
   uses further draws so two jitter candidates of one object differ).
4. :func:`score_rollouts` -> ``scores.csv``: self and anchored disagreement, implied
   physics and log error per (object, stand-in).
5. :func:`table1_metrics` -> ``metrics.json``: Table 1 and the oracle's recovery R^2.
   :func:`noise_sweep` -> ``noise.csv``: Table 2 (top). :func:`selection_study` ->
   ``selection.csv`` and ``selection_choices.csv``: Table 2 (bottom) plus the peers'
   rules.
6. :func:`section4_part` -> ``results/paper/parts/section4.json``: the numbers under
   the paper's macro names and the claims checked on them.

Seeds: ``section4.seed`` with a fixed stream per step (objects 1, jitter 2, noise 3,
selection 4), so changing one step's settings leaves the others' draws alone.
"""

from __future__ import annotations

import logging
from typing import Any

import numpy as np
import pandas as pd

from imply import metrics as M
from imply import standins as S
from imply.paper.parts import Claim, Number
from imply.score import Scorer
from imply.sim import SceneConfig
from imply.table import PushTable

log = logging.getLogger("imply.section4")

STREAM_OBJECTS, STREAM_JITTER, STREAM_NOISE, STREAM_SELECTION = 1, 2, 3, 4
# macro-name prefixes of the stand-ins (the paper's own: Or, Jit, Bl; Col is new)
PREFIX = {"oracle": "Or", "jitter": "Jit", "blind": "Bl", "collapse": "Col"}
# selection rules in table order, with macro-name stems (paper: First, Cons, Anch)
RULES = {
    "first": ("First candidate", "First"),
    "consensus": ("Consensus (median)", "Cons"),
    "anchored": ("Lowest anchored disagreement", "Anch"),
    "oracle": ("Oracle candidate (upper bound)", "Orac"),
    "self": ("Lowest self-disagreement (peer rule)", "Self"),
    "medoid": ("Medoid of the candidates (peer rule)", "Medoid"),
}
LETTERS = "ABCDEFGHIJKLMNOPQRSTUVWXYZ"


def rng_for(seed: int, stream: int) -> np.random.Generator:
    return np.random.default_rng([int(seed), int(stream)])


# -- 1. objects --------------------------------------------------------------------


def draw_objects(cfg: dict[str, Any], scene: SceneConfig, seed: int, table: PushTable | None = None) -> pd.DataFrame:
    """Evaluation and training objects: object_id, population, mass, friction, size_x/y/z."""
    mass, fric = cfg["mass"], cfg["friction"]
    for name, rng_ in (("mass", mass), ("friction", fric)):
        if not 0 < rng_["min"] <= rng_["max"]:
            raise ValueError(f"section4.objects.{name}: need 0 < min <= max")
    if table is not None:
        try:
            table.check_range(masses=[mass["min"], mass["max"]], frictions=[fric["min"], fric["max"]])
        except ValueError as exc:
            raise ValueError(f"section4.objects: {exc}") from exc
    rng = rng_for(seed, STREAM_OBJECTS)
    frames = []
    for population, n in (("eval", int(cfg["n"])), ("train", int(cfg["n_train"]))):
        if n < 2:
            raise ValueError(f"section4.objects: need at least 2 {population} objects")
        u = rng.random((n, 2))
        z = rng.standard_normal((n, 3))
        m = np.exp(np.log(mass["min"]) + u[:, 0] * np.log(mass["max"] / mass["min"]))
        mu = np.exp(np.log(fric["min"]) + u[:, 1] * np.log(fric["max"] / fric["min"]))
        size = np.asarray(scene.box_half_extents)[None, :] * np.exp(float(cfg["size_log_sd"]) * z)
        frames.append(
            pd.DataFrame(
                {
                    "object_id": [f"{population}{i:04d}" for i in range(n)],
                    "population": population,
                    "mass": m,
                    "friction": mu,
                    "size_x": size[:, 0],
                    "size_y": size[:, 1],
                    "size_z": size[:, 2],
                }
            )
        )
    return pd.concat(frames, ignore_index=True)


def _population(objects: pd.DataFrame, population: str) -> pd.DataFrame:
    return objects[objects["population"] == population].reset_index(drop=True)


def _sizes(objects: pd.DataFrame) -> np.ndarray:
    return objects[["size_x", "size_y", "size_z"]].to_numpy(float)


# -- 2. truth -----------------------------------------------------------------------


def simulate_truth(
    objects: pd.DataFrame, query_speeds, calib_speeds, scene: SceneConfig, nthread: int = 0, progress: bool = False
) -> pd.DataFrame:
    """True pushes, long format: object_id, population, role (calibration|query), speed, displacement, ok.

    One batch: evaluation objects at calibration + query speeds, training objects at
    query speeds (padded to the same speed list and dropped after, so a single call).
    """
    q = np.asarray(query_speeds, dtype=float)
    c = np.asarray(calib_speeds, dtype=float)
    speeds = np.concatenate([c, q])
    roles = ["calibration"] * c.size + ["query"] * q.size
    ev, tr = _population(objects, "eval"), _population(objects, "train")
    both = pd.concat([ev, tr], ignore_index=True)
    # training objects only need the query speeds; simulate them at the same list and drop
    # their calibration pushes: a few hundred extra pushes buy a single batched call
    disp, ok = S.oracle(
        speeds, both["mass"].to_numpy(float), both["friction"].to_numpy(float), _sizes(both),
        scene=scene, nthread=nthread, progress=progress,
    )  # fmt: skip
    n = len(both)
    frame = pd.DataFrame(
        {
            "object_id": np.repeat(both["object_id"].to_numpy(), speeds.size),
            "population": np.repeat(both["population"].to_numpy(), speeds.size),
            "role": np.tile(roles, n),
            "speed": np.tile(speeds, n),
            "displacement": disp.ravel(),
            "ok": ok.ravel(),
        }
    )
    keep = (frame["population"] == "eval") | (frame["role"] == "query")
    return frame[keep].reset_index(drop=True)


def truth_arrays(truth: pd.DataFrame, query_speeds, calib_speeds) -> dict[str, Any]:
    """Truth as arrays: ids, calib (N, C), query (N, K), train (M, K), in file order."""
    q = np.asarray(query_speeds, dtype=float)
    c = np.asarray(calib_speeds, dtype=float)
    out: dict[str, Any] = {"query_speeds": q, "calib_speeds": c}
    ev = truth[truth["population"] == "eval"]
    ids = list(dict.fromkeys(ev["object_id"]))
    out["ids"] = ids
    out["calib"] = _pivot(ev[ev["role"] == "calibration"], ids, c, "truth calibration")
    out["query"] = _pivot(ev[ev["role"] == "query"], ids, q, "truth query")
    tr = truth[truth["population"] == "train"]
    out["train"] = _pivot(tr, list(dict.fromkeys(tr["object_id"])), q, "truth training")
    return out


def _pivot(frame: pd.DataFrame, ids: list[str], speeds: np.ndarray, what: str) -> np.ndarray:
    """(len(ids), len(speeds)) displacements from a long frame; every cell must be present once."""
    table = frame.pivot_table(index="object_id", columns="speed", values="displacement", aggfunc="first")
    missing_speeds = [v for v in speeds if not np.any(np.isclose(table.columns.to_numpy(float), v))]
    if missing_speeds or len(frame) != len(ids) * speeds.size:
        raise ValueError(f"{what}: expected {len(ids)} objects x speeds {list(speeds)}, got {len(frame)} rows")
    cols = [table.columns[np.argmin(np.abs(table.columns.to_numpy(float) - v))] for v in speeds]
    return table.loc[ids, cols].to_numpy(float)


# -- 3. stand-ins -----------------------------------------------------------------


def make_standins(
    objects: pd.DataFrame,
    truth: pd.DataFrame,
    cfg: dict[str, Any],
    seed: int,
    table: PushTable,
    query_speeds,
    calib_speeds,
    floor: float,
    scene: SceneConfig,
    nthread: int = 0,
    progress: bool = False,
) -> pd.DataFrame:
    """Rollouts of every stand-in, long format: object_id, standin, draw, speed, displacement."""
    t = truth_arrays(truth, query_speeds, calib_speeds)
    ev = _population(objects, "eval").set_index("object_id").loc[t["ids"]]
    n, k = t["query"].shape
    q = t["query_speeds"]
    draws = int(cfg["jitter_draws"])
    jit, jok, _, _ = S.jitter(
        q, ev["mass"].to_numpy(float), ev["friction"].to_numpy(float), _sizes(ev),
        sd=float(cfg["jitter_sd"]), draws=draws, rng=rng_for(seed, STREAM_JITTER),
        mass_range=table.mass_range, friction_range=table.friction_range,
        scene=scene, nthread=nthread, progress=progress,
    )  # fmt: skip
    if not jok.all():
        log.warning("%d jitter pushes failed the simulator's checks; kept as simulated", int((~jok).sum()))
    sets = {
        # the oracle's rollouts are the true query pushes (same simulator, physics, geometry)
        "oracle": t["query"][:, None, :],
        "jitter": jit,
        "blind": S.object_blind(n, S.typical_displacement(t["train"]))[:, None, :],
        "collapse": S.collapse(n, k, floor)[:, None, :],
    }
    frames = []
    for name in S.STANDINS:
        arr = sets[name]
        nd = arr.shape[1]
        frames.append(
            pd.DataFrame(
                {
                    "object_id": np.repeat(t["ids"], nd * k),
                    "standin": name,
                    "draw": np.tile(np.repeat(np.arange(nd), k), n),
                    "speed": np.tile(q, n * nd),
                    "displacement": arr.ravel(),
                }
            )
        )
    return pd.concat(frames, ignore_index=True)


def rollout_arrays(rollouts: pd.DataFrame, ids: list[str], speeds) -> dict[str, np.ndarray]:
    """Stand-in rollouts as arrays: name -> (N, draws, K) in the given object order."""
    speeds = np.asarray(speeds, dtype=float)
    out = {}
    for name in S.STANDINS:
        sub = rollouts[rollouts["standin"] == name]
        if sub.empty:
            raise ValueError(f"rollouts have no {name!r} stand-in")
        nd = int(sub["draw"].max()) + 1
        out[name] = np.stack([_pivot(sub[sub["draw"] == j], ids, speeds, f"{name} draw {j}") for j in range(nd)], 1)
    return out


# -- 4. scores ------------------------------------------------------------------------


def make_scorer(table: PushTable, score_cfg: dict[str, Any]) -> Scorer:
    return Scorer(table, grid=int(score_cfg["grid"]), floor=float(score_cfg["readout_floor"]))


def score_rollouts(
    table: PushTable, objects: pd.DataFrame, truth: pd.DataFrame, rollouts: pd.DataFrame, score_cfg: dict[str, Any]
) -> pd.DataFrame:
    """Scores per (stand-in, object) of the Table 1 rollout sets (jitter: draw 0)."""
    q, c = score_cfg["query_speeds"], score_cfg["calibration_speeds"]
    t = truth_arrays(truth, q, c)
    r = rollout_arrays(rollouts, t["ids"], q)
    ev = _population(objects, "eval").set_index("object_id").loc[t["ids"]]
    scorer = make_scorer(table, score_cfg)
    n = len(t["ids"])
    sets = np.concatenate([r[name][:, 0, :] for name in S.STANDINS])
    sc = scorer.score(
        t["query_speeds"],
        sets,
        np.tile(t["calib_speeds"], (sets.shape[0], 1)),
        np.tile(t["calib"], (len(S.STANDINS), 1)),
    )
    return pd.DataFrame(
        {
            "standin": np.repeat(S.STANDINS, n),
            "object_id": np.tile(t["ids"], len(S.STANDINS)),
            "self_disagreement": sc.self_disagreement,
            "anchored_disagreement": sc.anchored_disagreement,
            "log_error": M.log_error(sets, np.tile(t["query"], (len(S.STANDINS), 1)), scorer.floor),
            "mass_hat": sc.mass_hat,
            "friction_hat": sc.friction_hat,
            "anchored_mass_hat": sc.anchored_mass_hat,
            "anchored_friction_hat": sc.anchored_friction_hat,
            "mass": np.tile(ev["mass"].to_numpy(float), len(S.STANDINS)),
            "friction": np.tile(ev["friction"].to_numpy(float), len(S.STANDINS)),
        }
    )


# -- 5. metrics -----------------------------------------------------------------------


def table1_metrics(scores: pd.DataFrame, table: PushTable, jitter_sd: float, k_speeds: int) -> dict[str, Any]:
    """Table 1 (per stand-in means, AUROC vs the oracle, corr(anchored, error)) and oracle recovery."""
    by = {name: scores[scores["standin"] == name].reset_index(drop=True) for name in S.STANDINS}
    orc = by["oracle"]
    rows: dict[str, dict[str, float | None]] = {}
    for name, f in by.items():
        row: dict[str, float | None] = {
            "self": float(f["self_disagreement"].mean()),
            "anchored": float(f["anchored_disagreement"].mean()),
            "log_error": float(f["log_error"].mean()),
            "auroc_self": None,
            "auroc_anchored": None,
            "corr_anchored_error": None,
        }
        if name != "oracle":
            row["auroc_self"] = M.auroc(orc["self_disagreement"], f["self_disagreement"])
            row["auroc_anchored"] = M.auroc(orc["anchored_disagreement"], f["anchored_disagreement"])
            row["corr_anchored_error"] = M.pearson(f["anchored_disagreement"], f["log_error"])
        rows[name] = row
    return {
        "n_objects": int(len(orc)),
        "k_speeds": int(k_speeds),
        "jitter_sd": float(jitter_sd),
        "table_shape": [int(table.speeds.size), int(table.masses.size), int(table.frictions.size)],
        "standins": rows,
        "oracle_recovery": {
            "mass_r2": M.r_squared(np.log(orc["mass"]), np.log(orc["mass_hat"])),
            "friction_r2": M.r_squared(np.log(orc["friction"]), np.log(orc["friction_hat"])),
        },
    }


def noise_sweep(
    table: PushTable,
    truth: pd.DataFrame,
    rollouts: pd.DataFrame,
    cfg: dict[str, Any],
    seed: int,
    score_cfg: dict[str, Any],
) -> pd.DataFrame:
    """Table 2 (top): every rollout's displacement times exp(sd z) before scoring.

    The same standard normal draws z are scaled for every sd (common random numbers),
    so the levels differ only by the noise's size; calibration pushes stay exact.
    Columns: sd, standin, mean_self, mean_anchored, auroc_self, auroc_anchored (the
    AUROCs against the oracle at the same sd; NaN for the oracle itself).
    """
    q, c = score_cfg["query_speeds"], score_cfg["calibration_speeds"]
    t = truth_arrays(truth, q, c)
    r = rollout_arrays(rollouts, t["ids"], q)
    n, k = t["query"].shape
    clean = np.stack([r[name][:, 0, :] for name in S.STANDINS])  # (4, N, K)
    z = rng_for(seed, STREAM_NOISE).standard_normal(clean.shape)
    sds = [float(s) for s in cfg["sds"]]
    noisy = np.concatenate([S.add_readout_noise(clean, sd, z).reshape(-1, k) for sd in sds])
    scorer = make_scorer(table, score_cfg)
    reps = noisy.shape[0]
    sc = scorer.score(
        t["query_speeds"], noisy, np.tile(t["calib_speeds"], (reps, 1)), np.tile(t["calib"], (reps // n, 1))
    )
    ns = len(S.STANDINS)
    self_ = sc.self_disagreement.reshape(len(sds), ns, n)
    anch = sc.anchored_disagreement.reshape(len(sds), ns, n)
    rows = []
    for i, sd in enumerate(sds):
        for j, name in enumerate(S.STANDINS):
            rows.append(
                {
                    "sd": sd,
                    "standin": name,
                    "mean_self": float(self_[i, j].mean()),
                    "mean_anchored": float(anch[i, j].mean()),
                    "auroc_self": np.nan if j == 0 else M.auroc(self_[i, 0], self_[i, j]),
                    "auroc_anchored": np.nan if j == 0 else M.auroc(anch[i, 0], anch[i, j]),
                }
            )
    return pd.DataFrame(rows)


def selection_study(
    table: PushTable,
    truth: pd.DataFrame,
    rollouts: pd.DataFrame,
    cfg: dict[str, Any],
    seed: int,
    score_cfg: dict[str, Any],
) -> tuple[pd.DataFrame, pd.DataFrame]:
    """Table 2 (bottom): choose among ``cfg['k']`` candidate rollout sets per object.

    Candidates: the oracle's set and k-1 sets drawn uniformly (with replacement) from
    the other stand-ins (each jitter candidate a different jitter draw), each with
    readout noise of sd ``cfg['noise_sd']``, in shuffled order. The miss is measured at
    ``cfg['query_speed']`` (one of the query speeds). Returns the per-rule summary
    (rule, label, median_miss_mm, share_within, picked_oracle, mean_log_error) and the
    per-object choices.
    """
    q, c = score_cfg["query_speeds"], score_cfg["calibration_speeds"]
    t = truth_arrays(truth, q, c)
    r = rollout_arrays(rollouts, t["ids"], q)
    n, k = t["query"].shape
    n_cand = int(cfg["k"])
    others = [s for s in S.STANDINS if s != "oracle"]
    if n_cand < 2:
        raise ValueError("section4.selection.k must be at least 2")
    if r["jitter"].shape[1] < n_cand - 1:
        raise ValueError(
            f"section4.selection.k={n_cand} needs section4.standins.jitter_draws >= {n_cand - 1}, "
            f"the rollouts have {r['jitter'].shape[1]}"
        )
    qi = np.flatnonzero(np.isclose(t["query_speeds"], float(cfg["query_speed"])))
    if qi.size != 1:
        raise ValueError(
            f"section4.selection.query_speed {cfg['query_speed']} is not one of the query speeds {list(q)}"
        )
    qi = int(qi[0])
    rng = rng_for(seed, STREAM_SELECTION)
    kinds = np.empty((n, n_cand), dtype=object)
    cands = np.empty((n, n_cand, k))
    kind_pick = rng.integers(0, len(others), size=(n, n_cand - 1))
    order = np.argsort(rng.random((n, n_cand)), axis=1)
    z = rng.standard_normal((n, n_cand, k))
    for i in range(n):
        raw = [("oracle", r["oracle"][i, 0])]
        used_jitter = 0
        for j in kind_pick[i]:
            name = others[j]
            if name == "jitter":
                raw.append((name, r["jitter"][i, used_jitter]))
                used_jitter += 1
            else:
                raw.append((name, r[name][i, 0]))
        for slot, src in enumerate(order[i]):
            kinds[i, slot] = raw[src][0]
            cands[i, slot] = raw[src][1]
    cands = S.add_readout_noise(cands, float(cfg["noise_sd"]), z)
    is_oracle = kinds == "oracle"

    scorer = make_scorer(table, score_cfg)
    flat = cands.reshape(-1, k)
    sc = scorer.score(
        t["query_speeds"], flat, np.tile(t["calib_speeds"], (flat.shape[0], 1)), np.repeat(t["calib"], n_cand, 0)
    )
    self_ = sc.self_disagreement.reshape(n, n_cand)
    anch = sc.anchored_disagreement.reshape(n, n_cand)
    chosen = {
        "first": M.select_first(n),
        "anchored": M.select_lowest(anch),
        "oracle": np.argmax(is_oracle, axis=1),
        "self": M.select_lowest(self_),
        "medoid": M.select_medoid(cands, scorer.floor),
    }
    true_q = t["query"][:, qi]
    rows, per_object = [], {"object_id": t["ids"], "candidates": [",".join(row) for row in kinds]}
    for rule, (label, _) in RULES.items():
        if rule == "consensus":
            sets = M.consensus(cands)
            picked = np.full(n, np.nan)
            idx = np.full(n, -1)
        else:
            idx = chosen[rule]
            sets = M.take(cands, idx)
            picked = is_oracle[np.arange(n), idx].astype(float)
        miss = M.miss_mm(sets[:, qi], true_q)
        per_object[f"{rule}_choice"] = idx
        per_object[f"{rule}_miss_mm"] = miss
        rows.append(
            {
                "rule": rule,
                "label": label,
                "median_miss_mm": float(np.median(miss)),
                "share_within": M.share_within(miss, float(cfg["within_mm"])),
                "picked_oracle": float(np.mean(picked)) if rule != "consensus" else np.nan,
                "mean_log_error": float(M.log_error(sets, t["query"], scorer.floor).mean()),
            }
        )
    return pd.DataFrame(rows), pd.DataFrame(per_object)


# -- 6. the paper part ---------------------------------------------------------------


def section4_numbers(
    metrics: dict[str, Any], noise: pd.DataFrame, selection: pd.DataFrame, cfg: dict[str, Any]
) -> dict[str, Number]:
    """Every Section 4 number under its macro name (the paper's where it has one)."""
    num: dict[str, Number] = {
        "nObjects": Number(metrics["n_objects"], "d"),
        "kSpeeds": Number(metrics["k_speeds"], "d"),
        "jitterSd": Number(metrics["jitter_sd"], ".2f"),
        "orMassR": Number(metrics["oracle_recovery"]["mass_r2"], ".3f"),
        "orFricR": Number(metrics["oracle_recovery"]["friction_r2"], ".3f"),
        "tableNSpeeds": Number(metrics["table_shape"][0], "d"),
        "tableNMasses": Number(metrics["table_shape"][1], "d"),
        "tableNFrictions": Number(metrics["table_shape"][2], "d"),
    }
    for name, row in metrics["standins"].items():
        p = PREFIX[name]
        num[f"{p}Self"] = Number(row["self"], ".3f")
        num[f"{p}Anch"] = Number(row["anchored"], ".3f")
        num[f"{p}Err"] = Number(row["log_error"], ".3f")
        if name != "oracle":
            num[f"{p}AurocSelf"] = Number(row["auroc_self"], ".2f")
            num[f"{p}AurocAnch"] = Number(row["auroc_anchored"], ".2f")
            num[f"{p}Corr"] = Number(_nan(row["corr_anchored_error"]), ".2f")

    sds = sorted(noise["sd"].unique())
    if len(sds) > len(LETTERS):
        raise ValueError("at most 26 noise levels")
    for i, sd in enumerate(sds):
        L = LETTERS[i]
        lvl = noise[noise["sd"] == sd].set_index("standin")
        num[f"noise{L}Sd"] = Number(float(sd), "g")
        num[f"noise{L}Oracle"] = Number(float(lvl.loc["oracle", "mean_anchored"]), ".3f")
        for name, word in (("jitter", "Jitter"), ("blind", "Blind"), ("collapse", "Collapse")):
            num[f"noise{L}{word}"] = Number(float(lvl.loc[name, "auroc_anchored"]), ".2f")
    top = noise[noise["sd"] == sds[-1]].set_index("standin")
    num["noiseMax"] = Number(float(sds[-1]), "g")
    num["noiseMaxAurocBlind"] = Number(float(top.loc["blind", "auroc_anchored"]), ".2f")

    sel = selection.set_index("rule")
    num["selK"] = Number(int(cfg["selection"]["k"]), "d")
    num["selQuerySpeed"] = Number(float(cfg["selection"]["query_speed"]), "g")
    num["selNoiseSd"] = Number(float(cfg["selection"]["noise_sd"]), "g")
    for rule, (_, stem) in RULES.items():
        num[f"sel{stem}Miss"] = Number(float(sel.loc[rule, "median_miss_mm"]), ".1f")
        num[f"sel{stem}Within"] = Number(100.0 * float(sel.loc[rule, "share_within"]), ".0f")
        num[f"sel{stem}Err"] = Number(float(sel.loc[rule, "mean_log_error"]), ".3f")
        if rule not in ("consensus", "anchored"):
            num[f"sel{stem}PickedOracle"] = Number(100.0 * float(sel.loc[rule, "picked_oracle"]), ".0f")
    num["selPickedOracle"] = Number(100.0 * float(sel.loc["anchored", "picked_oracle"]), ".0f")
    return num


def _nan(x: float | None) -> float:
    return float("nan") if x is None else float(x)


def section4_claims(v: dict[str, float]) -> list[Claim]:
    """The qualitative claims of Section 4 as checks with fixed, stated thresholds.

    ``v`` maps macro names to unrounded values. The thresholds were set from the
    paper's wording before any result was seen; a claim that fails is reported.
    """

    def claim(cid: str, statement: str, holds: bool, detail: str) -> Claim:
        return Claim(id=cid, section="4", statement=statement, holds=bool(holds), detail=detail)

    noise_letters = [L for L in LETTERS if f"noise{L}Sd" in v]
    oracle_scores = [v[f"noise{L}Oracle"] for L in noise_letters]
    other_aurocs = [v[f"noise{L}{w}"] for L in noise_letters for w in ("Jitter", "Collapse")]
    return [
        claim(
            "s4-oracle-near-zero",
            "The oracle's mean self-disagreement is near zero: below 0.02 (log units).",
            v["OrSelf"] < 0.02,
            f"oracle self {v['OrSelf']:.4f}",
        ),
        claim(
            "s4-oracle-recovers-physics",
            "The oracle's implied physics recovers the object: R^2 of implied log mass and of log friction both at least 0.9.",
            v["orMassR"] >= 0.9 and v["orFricR"] >= 0.9,
            f"mass R^2 {v['orMassR']:.3f}, friction R^2 {v['orFricR']:.3f}",
        ),
        claim(
            "s4-self-catches-jitter-collapse",
            "Self-disagreement alone separates jitter and collapse from the oracle perfectly: both self AUROCs at least 0.99.",
            v["JitAurocSelf"] >= 0.99 and v["ColAurocSelf"] >= 0.99,
            f"jitter {v['JitAurocSelf']:.3f}, collapse {v['ColAurocSelf']:.3f}",
        ),
        claim(
            "s4-blind-self-like-oracle",
            "The object-blind model's mean self-disagreement is near zero like the oracle's: below 0.02.",
            v["BlSelf"] < 0.02,
            f"blind self {v['BlSelf']:.4f} vs oracle {v['OrSelf']:.4f}",
        ),
        claim(
            "s4-blind-self-auroc-far-below-anchored",
            "Self-disagreement AUROC of the object-blind model is far below anchored: lower by at least 0.2.",
            v["BlAurocAnch"] - v["BlAurocSelf"] >= 0.2,
            f"self {v['BlAurocSelf']:.3f} vs anchored {v['BlAurocAnch']:.3f}",
        ),
        claim(
            "s4-blind-error-as-large-as-jitter",
            "The object-blind model's log error is as large as jitter's: at least 0.75 times it.",
            v["BlErr"] >= 0.75 * v["JitErr"],
            f"blind {v['BlErr']:.3f} vs jitter {v['JitErr']:.3f}",
        ),
        claim(
            "s4-anchored-exposes-blind",
            "Anchoring exposes the object-blind model: anchored AUROC against the oracle at least 0.95, "
            "and its mean anchored disagreement at least 5 times its self-disagreement.",
            v["BlAurocAnch"] >= 0.95 and v["BlAnch"] >= 5 * v["BlSelf"],
            f"AUROC {v['BlAurocAnch']:.3f}; anchored {v['BlAnch']:.3f} vs self {v['BlSelf']:.4f}",
        ),
        claim(
            "s4-anchored-tracks-error",
            "Anchored disagreement correlates with log error within the jitter model and within the object-blind "
            "model: both Pearson r at least 0.8.",
            v["JitCorr"] >= 0.8 and v["BlCorr"] >= 0.8,
            f"jitter r {v['JitCorr']:.3f}, blind r {v['BlCorr']:.3f}",
        ),
        claim(
            "s4-collapse-far",
            "Collapse is far from the oracle: mean self and anchored disagreement both above 1 (log units).",
            v["ColSelf"] > 1 and v["ColAnch"] > 1,
            f"self {v['ColSelf']:.3f}, anchored {v['ColAnch']:.3f}",
        ),
        claim(
            "s4-noise-oracle-rises",
            "The oracle's anchored score rises with readout noise: strictly increasing over the noise levels.",
            bool(np.all(np.diff(oracle_scores) > 0)),
            "oracle score " + ", ".join(f"{s:.3f}" for s in oracle_scores),
        ),
        claim(
            "s4-noise-separation-survives",
            "Jitter and collapse stay separated from the oracle at every noise level: anchored AUROC at least 0.9.",
            min(other_aurocs) >= 0.9,
            f"lowest {min(other_aurocs):.3f}",
        ),
        claim(
            "s4-noise-max-blind-separated",
            f"At the largest readout noise (sd {v['noiseMax']:g}) the object-blind model is still separated: "
            "anchored AUROC at least 0.7.",
            v["noiseMaxAurocBlind"] >= 0.7,
            f"AUROC {v['noiseMaxAurocBlind']:.3f}",
        ),
        claim(
            "s4-sel-anchored-picks-oracle",
            "Lowest anchored disagreement picks the oracle candidate most of the time: more than 50% of objects.",
            v["selPickedOracle"] > 50,
            f"{v['selPickedOracle']:.1f}%",
        ),
        claim(
            "s4-sel-anchored-beats-first-and-consensus",
            "Selecting by anchored disagreement lowers the median miss below both the first candidate's and the consensus'.",
            v["selAnchMiss"] < v["selFirstMiss"] and v["selAnchMiss"] < v["selConsMiss"],
            f"anchored {v['selAnchMiss']:.2f} mm, first {v['selFirstMiss']:.2f} mm, consensus {v['selConsMiss']:.2f} mm",
        ),
        claim(
            "s4-sel-consensus-no-better",
            "Consensus does no better than the first candidate: its median miss is not lower.",
            v["selConsMiss"] >= v["selFirstMiss"],
            f"consensus {v['selConsMiss']:.2f} mm vs first {v['selFirstMiss']:.2f} mm",
        ),
        claim(
            "s4-sel-anchored-near-oracle",
            "Anchored selection's median miss is close to the oracle candidate's: within 1 mm.",
            abs(v["selAnchMiss"] - v["selOracMiss"]) <= 1.0,
            f"anchored {v['selAnchMiss']:.2f} mm vs oracle {v['selOracMiss']:.2f} mm",
        ),
    ]


def section4_part(
    metrics: dict[str, Any], noise: pd.DataFrame, selection: pd.DataFrame, cfg: dict[str, Any]
) -> tuple[dict[str, Number], list[Claim]]:
    """Numbers and checked claims of Section 4, ready for :func:`imply.paper.parts.write_part`."""
    numbers = section4_numbers(metrics, noise, selection, cfg)
    values = {k: float(n.value) for k, n in numbers.items()}
    return numbers, section4_claims(values)
