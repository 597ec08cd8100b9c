"""The pixel-space video model (imply.models.pixel_video) trained on the training clips and measured on the
validation split only (never the held-out objects): does it move with the action, can the frame readout read
its frames, does it track the object from calibration, and can the anchored score choose among its samples.

Run (after ``snakemake --cores 2 results/clips/train.npz results/clips/validation.npz results/table/table.npz``):

    python benchmarks/pixel_video_validation.py --variant calib [--epochs 20] [--set keypoint_sd=0.2] [--save /tmp/pv_calib.pt]
    python benchmarks/pixel_video_validation.py --variant nocalib --sets 16

The frame-difference readout is fitted on the real training clips (first and rest frames), never on generated
ones. Prints, for sample 0 (the prior's mean) and for ``--sets`` sample sets: the mean per-object slope of
generated log slide against log speed beside the true one; the box's saliency mass in generated rest frames
against the real ones' (median ratio); PSNR of generated against true rest frames; tracking r and mean log
error with the object's own calibration and with another object's (calibrated variant); the spread of the
per-object mean log slide across sample sets; and choosing one of the sets by the lowest anchored
disagreement, by the lowest self-disagreement, at random and by the true error (the oracle).
Benchmarks measure; they assert nothing.
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from imply.data.clips import load_clips
from imply.models.pixel_video import PixelVideoConfig, generate, save_pixel_video, train_pixel_video
from imply.options import default_of
from imply.readout import FrameDiffReadout, saliency
from imply.score import score_sets
from imply.table import PushTable


def _corr(a: np.ndarray, b: np.ndarray) -> float:
    return float(np.corrcoef(a, b)[0, 1])


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--variant", choices=("calib", "nocalib"), default="calib")
    ap.add_argument("--epochs", type=int, default=default_of(PixelVideoConfig, "epochs"))
    ap.add_argument("--sets", type=int, default=16, help="sample sets per object")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument(
        "--set",
        action="append",
        default=[],
        metavar="KEY=VALUE",
        help="override a PixelVideoConfig field (repeatable), e.g. --set keypoint_sd=0.2",
    )
    ap.add_argument("--save", default=None, help="save the trained weights here")
    ap.add_argument("--clips", default="results/clips")
    ap.add_argument("--table", default="results/table/table.npz")
    args = ap.parse_args(argv)

    frames, meta = load_clips(f"{args.clips}/train.npz")
    vf, vm = load_clips(f"{args.clips}/validation.npz")
    overrides = {}
    for item in args.set:
        key, _, value = item.partition("=")
        kind = type(getattr(PixelVideoConfig(), key))
        overrides[key] = value.lower() in ("1", "true", "yes") if kind is bool else kind(value)
    cfg = PixelVideoConfig(epochs=args.epochs, seed=args.seed, **overrides)
    calibrated = args.variant == "calib"
    t0 = time.perf_counter()
    model, _ = train_pixel_video(frames, meta, cfg, calibrated=calibrated, threads=args.threads)
    print(
        f"{args.variant} {' '.join(args.set)}: trained {args.epochs} epochs on {len(frames)} training clips in "
        f"{time.perf_counter() - t0:.0f} s"
    )
    if args.save:
        save_pixel_video(args.save, model, [])
    readout = FrameDiffReadout.fit(frames, meta["displacement"].to_numpy())
    table = PushTable.load(args.table)

    objs = vm["object_id"].unique()
    n = len(objs)
    q = vm[vm["role"] == "query"]
    qi = q.index.to_numpy().reshape(n, -1)
    speeds = q["speed"].to_numpy().reshape(n, -1)[0]
    cal = np.stack([vm.index[vm["role"] == f"calibration_{j}"].to_numpy() for j in (0, 1)], 1)
    true = vm["displacement"].to_numpy()[qi]
    cal_d = vm["displacement"].to_numpy()[cal]
    cal_speeds = vm["speed"].to_numpy()[cal[0]]  # the split's calibration speeds (config score.calibration_speeds)
    other = np.roll(np.arange(n), 1)  # another object's calibration

    def rollout(sample: int, calib_of: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        g = generate(
            model,
            context=vf[qi, 0],
            speeds=speeds,
            sample=sample,
            calib_first=vf[cal[calib_of], 0],
            calib_rest=vf[cal[calib_of], -1],
            calib_speed=cal_speeds,
            seed=args.seed,
        )
        rest = g[:, :, -1]
        clips = np.stack([vf[qi, 0], rest], 2).reshape(-1, 2, *rest.shape[2:])
        return readout.predict(clips).reshape(n, -1), rest

    lt = np.log(true)
    own, rest = rollout(0, np.arange(n))
    lp = np.log(own)
    slope_gen = np.polyfit(np.log(speeds), lp.T, 1)[0]
    slope_true = np.polyfit(np.log(speeds), lt.T, 1)[0]
    real_rest = vf[qi, -1]
    mass_ratio = saliency(rest).sum((-2, -1)) / np.maximum(saliency(real_rest).sum((-2, -1)), 1e-9)
    mse = ((rest.astype(float) - real_rest.astype(float)) ** 2).mean((-3, -2, -1))
    psnr = 10 * np.log10(255.0**2 / np.maximum(mse, 1e-12))
    print(
        f"  moves with the action: per-object slope of log slide on log speed {slope_gen.mean():.3f} generated, "
        f"{slope_true.mean():.3f} true (ratio {slope_gen.mean() / slope_true.mean():.3f})"
    )
    print(
        f"  frames the readout can read: saliency mass of generated rest frames / real, median "
        f"{np.median(mass_ratio):.3f} (IQR {np.percentile(mass_ratio, 25):.3f}-{np.percentile(mass_ratio, 75):.3f}); "
        f"PSNR of rest frames median {np.median(psnr):.1f} dB"
    )
    print(f"  sample 0: tracking r {_corr(lp.mean(1), lt.mean(1)):.3f}, mean |log error| {np.abs(lp - lt).mean():.3f}")
    if calibrated:
        oth, _ = rollout(0, other)
        lo = np.log(oth)
        s_own = score_sets(table, speeds, own, cal_speeds, cal_d)
        s_oth = score_sets(table, speeds, oth, cal_speeds, cal_d)
        print(
            f"  another object's calibration: tracking r {_corr(lo.mean(1), lt.mean(1)):.3f}, mean |log error| "
            f"{np.abs(lo - lt).mean():.3f}; anchored prefers own on "
            f"{np.mean(s_own.anchored_disagreement < s_oth.anchored_disagreement):.1%} of {n} objects, self on "
            f"{np.mean(s_own.self_disagreement < s_oth.self_disagreement):.1%}"
        )
    if args.sets > 1:
        sets = np.stack([rollout(s, np.arange(n))[0] for s in range(1, args.sets + 1)])  # (S, n, K)
        spread = np.log(sets).mean(2).std(0)
        print(f"  spread of the per-object mean log slide across {args.sets} sample sets: mean {spread.mean():.3f}")
        scores = [score_sets(table, speeds, sets[s], cal_speeds, cal_d) for s in range(args.sets)]
        anch = np.stack([sc.anchored_disagreement for sc in scores])
        selfd = np.stack([sc.self_disagreement for sc in scores])
        err = np.abs(np.log(sets) - lt[None]).mean(2)
        rng = np.random.default_rng(args.seed)
        for name, pick in (
            ("anchored", anch.argmin(0)),
            ("self", selfd.argmin(0)),
            ("random", rng.integers(0, args.sets, n)),
            ("oracle", err.argmin(0)),
        ):
            chosen = np.log(sets[pick, np.arange(n)])
            print(
                f"  chosen by {name:8s}: tracking r {_corr(chosen.mean(1), lt.mean(1)):.3f}, mean |log error| "
                f"{np.abs(chosen - lt).mean():.3f}"
            )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
