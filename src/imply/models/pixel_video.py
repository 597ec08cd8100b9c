"""A small action-conditioned, stochastic video model in pixel space: the push's frames from its first one.

The family is stochastic variational video prediction with an advection decoder (CDNA:
Finn, Goodfellow and Levine 2016; its stochastic form SV2P: Babaeizadeh et al. 2018), cut
down to a fixed camera and one moving object so that it trains on two CPU cores:

- **advection**: each generated frame is the table (a learned image per frame index, the
  pusher included) with the context frame's box (a learned soft mask of it) moved along
  the push by a sub-pixel translation. The translation is what the dynamics predict, so
  the generated box is one blob of the context box's size, never a smear;
- **dynamics**: per generated frame, the log of the slide in pixels is a quadratic in the
  log commanded speed whose three coefficients an MLP reads from the context frame's
  features and a latent ``z`` (and, in the calibrated variant, the two calibration
  pushes). Speed enters only there: an earlier design fed it to the MLP beside the
  calibration, which leaned on the calibration and used the speed too little (docs/notes/pixel-model.md);
- **keypoints, not labels**: the slide a training clip shows is the shift of the red box's
  centroid column between its first frame and each target frame (:func:`box_column`),
  read off the pixels; the metre labels of the clips are never used. The calibration
  pushes enter the same way;
- **stochastic**: ``z`` is drawn once per sample set (one object, all K query speeds), so a
  set describes one hypothetical object and sets differ in the object they imagine. Its
  prior is N(0, I) without calibration and a Gaussian read from the calibration pushes with
  it. Training maximises an evidence lower bound whose likelihood is the keypoints' (log
  slide, sd ``keypoint_sd``) with a posterior that sees every push of the set (each
  object's pushes share one ``z``), beside a pixel reconstruction error that fits the
  mask and the table.

Shapes: frames are uint8 (..., H, W, 3) at the interface and float (..., 3, H, W) in
[0, 1] inside. :class:`PixelVideoModel` is the network; :func:`train_pixel_video` fits it
on a clip split (:func:`imply.data.clips.load_clips`); :func:`generate` draws sample sets;
:class:`PixelVideoWorldModel` runs it behind ``imply evaluate``'s interface (kind
``frames``, stochastic).
"""

from __future__ import annotations

import logging
import math
import os
import pickle
import time
import warnings
import zlib
from dataclasses import dataclass

import numpy as np
import pandas as pd
import torch
import torch.nn.functional as F
from torch import nn
from tqdm.auto import tqdm

from imply.models.config import PixelVideoConfig

log = logging.getLogger("imply.models.pixel_video")

KEYPOINT_OFFSET = 0.5  # px: log(slide + this), so a box that hardly moves has a finite log slide
REFERENCE_SPEED = 0.5  # m/s: the log speed polynomial is centred here


def to_float(frames: np.ndarray | torch.Tensor) -> torch.Tensor:
    """uint8 (..., H, W, 3) -> float (..., 3, H, W) in [0, 1]."""
    x = torch.as_tensor(np.asarray(frames))
    return x.movedim(-1, -3).float() / 255.0


def to_uint8(x: torch.Tensor) -> np.ndarray:
    """float (..., 3, H, W) in [0, 1] -> uint8 (..., H, W, 3)."""
    return (x.clamp(0, 1) * 255.0).round().to(torch.uint8).movedim(-3, -1).numpy()


def box_column(frames: torch.Tensor, *, threshold: float = 0.1) -> torch.Tensor:
    """The red box's centroid column (N,) in frames (N, 3, H, W): columns weighted by red minus green above
    ``threshold`` (the table and pusher are grey, the box red)."""
    red = (frames[:, 0] - frames[:, 1] - threshold).clamp(min=0).sum(-2)  # (N, W)
    cols = torch.arange(red.shape[-1], dtype=red.dtype)
    return (red * cols).sum(-1) / red.sum(-1).clamp(min=1e-6)


def log_slide(first: torch.Tensor, later: torch.Tensor) -> torch.Tensor:
    """log(slide + KEYPOINT_OFFSET) of the box between frames (N, 3, H, W) and (N, 3, H, W), slide in pixels."""
    return torch.log((box_column(later) - box_column(first)).clamp(min=0) + KEYPOINT_OFFSET)


class FrameFeatures(nn.Module):
    """A frame (B, 3, H, W) -> features (B, width): three strided convolutions and a mean over the image."""

    def __init__(self, width: int) -> None:
        super().__init__()
        self.net = nn.Sequential(
            nn.Conv2d(3, width, 3, stride=2, padding=1),
            nn.GELU(),
            nn.Conv2d(width, width, 3, stride=2, padding=1),
            nn.GELU(),
            nn.Conv2d(width, width, 3, stride=2, padding=1),
            nn.GELU(),
        )
        # the box's column matters, not only what it looks like: a column-weighted pooling beside the mean
        self.out = nn.Linear(2 * width, width)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        h = self.net(x)
        cols = torch.linspace(-1, 1, h.shape[-1], device=h.device)
        pooled = torch.cat([h.mean((-2, -1)), (h.mean(-2) * cols).mean(-1)], -1)
        return self.out(pooled)


def translate(x: torch.Tensor, shift: torch.Tensor) -> torch.Tensor:
    """``x`` (B, C, H, W) moved ``shift`` (B,) pixels along W (sub-pixel: linear interpolation; zeros enter)."""
    b, _, h, w = x.shape
    src = torch.arange(w, dtype=x.dtype) - shift[:, None]  # (B, W): the source column of each output column
    gx = (2 * src + 1) / w - 1  # align_corners=False: pixel centre i sits at (2i + 1) / w - 1
    gy = (2 * torch.arange(h, dtype=x.dtype) + 1) / h - 1
    grid = torch.stack([gx[:, None, :].expand(b, h, w), gy[None, :, None].expand(b, h, w)], -1)
    return F.grid_sample(x, grid, mode="bilinear", padding_mode="zeros", align_corners=False)


def mlp(n_in: int, width: int, n_out: int) -> nn.Sequential:
    return nn.Sequential(nn.Linear(n_in, width), nn.GELU(), nn.Linear(width, width), nn.GELU(), nn.Linear(width, n_out))


class PixelVideoModel(nn.Module):
    """The network: features, mask, the table per frame index, the latent's prior and posterior, the dynamics."""

    def __init__(
        self,
        cfg: PixelVideoConfig,
        *,
        calibrated: bool,
        frame_shape: tuple[int, int],
        background: np.ndarray | None = None,
        mean_log_slide: np.ndarray | None = None,
    ):
        super().__init__()
        self.cfg = cfg
        self.calibrated = bool(calibrated)
        h, w = frame_shape
        n_f = len(cfg.frames)
        self.features = FrameFeatures(cfg.width)
        self.mask_net = nn.Sequential(nn.Conv2d(3, 8, 3, padding=1), nn.GELU(), nn.Conv2d(8, 1, 3, padding=1))
        nn.init.zeros_(self.mask_net[-1].weight)
        nn.init.zeros_(self.mask_net[-1].bias)
        # the box is the red thing on a grey table: the mask starts as a steep function of red minus green and
        # the network learns what to change; from a uniform start it never found it
        self.mask_gain = nn.Parameter(torch.tensor(40.0))
        self.mask_bias = nn.Parameter(torch.tensor(-4.0))
        bg = torch.full((n_f, 3, h, w), 0.33) if background is None else to_float(background)
        self.background = nn.Parameter(bg.clone())
        c = cfg.width if calibrated else 0
        # per calibration push: its first frame's features, its log speed and its log keypoint slide
        self.calibration = nn.Sequential(nn.Linear(2 * (cfg.width + 2), cfg.width), nn.GELU()) if c else None
        self.prior = nn.Linear(c, 2 * cfg.latent) if c else None
        # posterior: per push (context features, log speed, log keypoint slide at rest), pooled over the set
        self.posterior_push = nn.Sequential(nn.Linear(cfg.width + 2, cfg.width), nn.GELU())
        self.posterior = mlp(cfg.width + c, cfg.width, 2 * cfg.latent)
        # per frame index: the coefficients of log slide = a + b x + c x^2, x = log(speed / REFERENCE_SPEED)
        self.dynamics = mlp(cfg.width + cfg.latent + c, 2 * cfg.width, 3 * n_f)
        nn.init.zeros_(self.dynamics[-1].weight)
        start = np.zeros(n_f) if mean_log_slide is None else np.asarray(mean_log_slide, dtype=np.float32)
        with torch.no_grad():
            self.dynamics[-1].bias.copy_(torch.cat([torch.as_tensor(start), torch.ones(n_f), torch.zeros(n_f)]))

    # -- pieces -------------------------------------------------------------------------
    def mask(self, frame: torch.Tensor) -> torch.Tensor:
        """The box's soft mask (N, 1, H, W) in frames (N, 3, H, W)."""
        red = (frame[:, :1] - frame[:, 1:2]).clamp(min=0)
        return torch.sigmoid(self.mask_net(frame) + self.mask_gain * red + self.mask_bias)

    def table(self, f: int) -> torch.Tensor:
        """The table at frame index ``f`` (3, H, W), red no more than green: the box is the only red thing in a
        generated frame. A learned table picked up a faint red where boxes often rest, which the frame readout
        (red minus green) counted as box: slides of 2 cm read 0.6 cm longer."""
        bg = self.background[f]
        return torch.cat([torch.minimum(bg[:1], bg[1:2]), bg[1:]], 0)

    def calibration_summary(self, calib_first, calib_rest, calib_speed) -> torch.Tensor | None:
        """(B, 2, 3, H, W) first and rest frames of the two calibration pushes, (B, 2) speeds -> (B, width)."""
        if self.calibration is None:
            return None
        b = calib_first.shape[0]
        first, rest = calib_first.flatten(0, 1), calib_rest.flatten(0, 1)
        f0 = self.features(first).view(b, 2, -1)
        slide = log_slide(first, rest).view(b, 2, 1)
        x = torch.cat([f0, torch.log(calib_speed).unsqueeze(-1), slide], -1).flatten(1)
        return self.calibration(x)

    def prior_of(self, cal: torch.Tensor | None, b: int) -> tuple[torch.Tensor, torch.Tensor]:
        if self.prior is None:
            z = torch.zeros(b, self.cfg.latent)
            return z, z
        mu, logvar = self.prior(cal).chunk(2, -1)
        return mu, logvar.clamp(-8, 4)

    def posterior_of(self, ctx_feat, log_speed, rest_slide, cal, set_index, n_sets):
        """Per push features (N, ...) pooled per set (``set_index`` (N,) in 0 .. n_sets - 1) -> (n_sets, latent) x 2."""
        x = self.posterior_push(torch.cat([ctx_feat, log_speed.unsqueeze(-1), rest_slide.unsqueeze(-1)], -1))
        pooled = torch.zeros(n_sets, x.shape[-1]).index_add_(0, set_index, x)
        pooled = pooled / torch.bincount(set_index, minlength=n_sets).clamp(min=1).unsqueeze(-1)
        if cal is not None:
            pooled = torch.cat([pooled, cal], -1)
        mu, logvar = self.posterior(pooled).chunk(2, -1)
        return mu, logvar.clamp(-8, 4)

    def log_slides(
        self, feat: torch.Tensor, log_speed: torch.Tensor, z: torch.Tensor, cal: torch.Tensor | None
    ) -> torch.Tensor:
        """log(slide + KEYPOINT_OFFSET) (N, F) of each generated frame, slide in pixels."""
        coef = self.dynamics(torch.cat([feat, z] + ([cal] if cal is not None else []), -1))
        a, b, c = coef.view(len(feat), 3, len(self.cfg.frames)).unbind(1)
        x = (log_speed - math.log(REFERENCE_SPEED)).unsqueeze(-1)
        return a + b * x + c * x * x

    def render(
        self,
        context: torch.Tensor,
        log_speed: torch.Tensor,
        z: torch.Tensor,
        cal: torch.Tensor | None,
        *,
        features: torch.Tensor | None = None,
        detach_slides: bool = False,
    ):
        """Frames (N, F, 3, H, W) generated from context frames (N, 3, H, W), log speeds (N,), latents (N, latent)
        and calibration summaries (N, width) or None; and their log slides (N, F). ``features``: the context
        frames' features where the caller has them already."""
        feat = self.features(context) if features is None else features
        u = self.log_slides(feat, log_speed, z, cal)
        shift = ((u.detach() if detach_slides else u).exp() - KEYPOINT_OFFSET).clamp(min=0)
        m = self.mask(context)  # (N, 1, H, W): the box
        box = torch.cat([context * m, m], 1)
        frames = []
        for f in range(u.shape[1]):
            moved = translate(box, shift[:, f])
            rgb, alpha = moved[:, :3], moved[:, 3:].clamp(0, 1)
            frames.append(self.table(f) * (1 - alpha) + rgb)
        return torch.stack(frames, 1), u


# -- data -----------------------------------------------------------------------------------
@dataclass(frozen=True)
class Pushes:
    """The training pushes of a clip split, grouped into sets (one per object): tensors on the CPU.

    context: (N, 3, H, W) first frames; target: (N, F, 3, H, W) the frames to generate; slide: (N, F)
    their keypoint log slides (:func:`log_slide`); log_speed: (N,); set_index: (N,) the object of each
    push; calib_first, calib_rest: (n_sets, 2, 3, H, W); calib_speed: (n_sets, 2).
    """

    context: torch.Tensor
    target: torch.Tensor
    slide: torch.Tensor
    log_speed: torch.Tensor
    set_index: torch.Tensor
    calib_first: torch.Tensor
    calib_rest: torch.Tensor
    calib_speed: torch.Tensor

    @property
    def n_sets(self) -> int:
        return int(self.calib_speed.shape[0])


def training_pushes(frames: np.ndarray, meta: pd.DataFrame, cfg: PixelVideoConfig, *, calibrated: bool) -> Pushes:
    """The pushes a variant trains on, from a clip split laid out like ``train`` (2 calibration + query clips
    per object). Calibrated: the query clips, conditioned on their object's calibration clips. Without
    calibration: every clip, one set per object (its latent is the object)."""
    objs = meta["object_id"].to_numpy()
    order = {o: i for i, o in enumerate(dict.fromkeys(objs))}
    cal0 = meta.index[meta["role"] == "calibration_0"].to_numpy()
    cal1 = meta.index[meta["role"] == "calibration_1"].to_numpy()
    if not (len(cal0) == len(cal1) == len(order)):
        raise ValueError("every object needs its two calibration clips (roles calibration_0 and calibration_1)")
    cal = np.stack([cal0, cal1], 1)
    rows = meta.index[meta["role"] == "query"].to_numpy() if calibrated else meta.index.to_numpy()
    fr = list(cfg.frames)
    context, target = to_float(frames[rows, 0]), to_float(frames[rows][:, fr])
    slide = torch.stack([log_slide(context, target[:, i]) for i in range(len(fr))], 1)
    return Pushes(
        context=context,
        target=target,
        slide=slide,
        log_speed=torch.as_tensor(np.log(meta["speed"].to_numpy()[rows]), dtype=torch.float32),
        set_index=torch.as_tensor([order[o] for o in objs[rows]]),
        calib_first=to_float(frames[cal, 0]),
        calib_rest=to_float(frames[cal, -1]),
        calib_speed=torch.as_tensor(meta["speed"].to_numpy()[cal], dtype=torch.float32),
    )


def frame_loss(
    gen: torch.Tensor, target: torch.Tensor, *, profile_weight: float, scales: tuple[int, ...] = (1, 4, 16)
) -> torch.Tensor:
    """Pixel mean squared error, plus ``profile_weight`` times that of the frames' column profiles (each column's
    mean over the rows) averaged over 1, 4 and 16 columns: a box of a few pixels is a sliver of the frame's
    squared error, its column profile is not."""
    g, t = gen.flatten(0, 1), target.flatten(0, 1)
    pg, pt = g.mean(-2, keepdim=True), t.mean(-2, keepdim=True)
    profile = sum(F.mse_loss(F.avg_pool2d(pg, (1, k)), F.avg_pool2d(pt, (1, k))) for k in scales) / len(scales)
    return F.mse_loss(g, t) + profile_weight * profile


def training_loss(model: PixelVideoModel, p: Pushes, sets: torch.Tensor) -> tuple[torch.Tensor, dict]:
    """The loss on the pushes of ``sets`` (indices into p's sets): the negative ELBO of the keypoint slides in
    nats per push (Gaussian likelihood of sd ``keypoint_sd``; the KL of each set's latent shared by its pushes),
    plus ``pixel_weight`` times :func:`frame_loss`."""
    cfg = model.cfg
    pick = torch.isin(p.set_index, sets)
    remap = torch.full((p.n_sets,), -1, dtype=torch.long)
    remap[sets] = torch.arange(len(sets))
    idx = remap[p.set_index[pick]]
    cal = model.calibration_summary(p.calib_first[sets], p.calib_rest[sets], p.calib_speed[sets])
    ctx, tgt, ls, slide = p.context[pick], p.target[pick], p.log_speed[pick], p.slide[pick]
    ctx_f = model.features(ctx)
    mu_q, lv_q = model.posterior_of(ctx_f, ls, slide[:, -1], cal, idx, len(sets))
    mu_p, lv_p = model.prior_of(cal, len(sets))
    z = mu_q + torch.randn_like(mu_q) * (0.5 * lv_q).exp()
    gen, u = model.render(
        ctx, ls, z[idx], cal[idx] if cal is not None else None, features=ctx_f, detach_slides=not cfg.pixels_move_box
    )
    nll = ((u - slide) ** 2).sum(-1).mean() / (2 * cfg.keypoint_sd**2)
    kl = 0.5 * (lv_p - lv_q + ((lv_q.exp() + (mu_q - mu_p) ** 2) / lv_p.exp()) - 1).sum(-1)
    pixels = frame_loss(gen, tgt, profile_weight=cfg.profile_weight)
    loss = nll + kl.sum() / len(ctx) + cfg.pixel_weight * pixels
    return loss, {"nll": float(nll.detach()), "kl": float(kl.mean().detach()), "pixels": float(pixels.detach())}


def empty_table(frames: np.ndarray, *, red: int = 30) -> np.ndarray:
    """The table without the box, per frame index: uint8 (F, H, W, 3), the median over clips (N, F, H, W, 3) of
    each pixel where no box covers it (red minus green below ``red``), the overall median where one always does."""
    f = frames.astype(np.float32)
    covered = (f[..., 0] - f[..., 1]) >= red
    free = np.where(covered[..., None], np.nan, f)
    with warnings.catch_warnings():  # a pixel always covered is all NaN: it takes the overall median below
        warnings.simplefilter("ignore", RuntimeWarning)
        out = np.nanmedian(free, axis=0)
    return np.where(np.isnan(out), np.median(f, axis=0), out).round().astype(np.uint8)


def train_pixel_video(
    frames: np.ndarray,
    meta: pd.DataFrame,
    cfg: PixelVideoConfig,
    *,
    calibrated: bool,
    threads: int = 2,
    progress: bool = True,
) -> tuple[PixelVideoModel, list[dict]]:
    """Fit the calibrated variant or the one without calibration on a clip split (uint8 frames
    (N, T, H, W, 3) and its metadata); returns it and the history (one dict per epoch: the ELBO's nll
    and kl, the pixel error, the seconds it took)."""
    torch.manual_seed(cfg.seed)
    torch.set_num_threads(threads)
    p = training_pushes(frames, meta, cfg, calibrated=calibrated)
    bg = empty_table(frames[:: max(1, len(frames) // 400)][:, list(cfg.frames)])
    model = PixelVideoModel(
        cfg, calibrated=calibrated, frame_shape=frames.shape[2:4], background=bg, mean_log_slide=p.slide.mean(0).numpy()
    )
    opt = torch.optim.AdamW(model.parameters(), lr=cfg.lr, weight_decay=1e-4)
    steps = cfg.epochs * math.ceil(p.n_sets / cfg.batch_size)
    sched = torch.optim.lr_scheduler.OneCycleLR(opt, max_lr=cfg.lr, total_steps=steps, pct_start=0.1)
    gen = torch.Generator().manual_seed(cfg.seed)
    history = []
    for epoch in tqdm(range(cfg.epochs), desc="pixel video model", unit="epoch", disable=not progress):
        start = time.perf_counter()
        perm = torch.randperm(p.n_sets, generator=gen)
        totals = {"nll": 0.0, "kl": 0.0, "pixels": 0.0}
        for i in range(0, p.n_sets, cfg.batch_size):
            loss, parts = training_loss(model, p, perm[i : i + cfg.batch_size])
            opt.zero_grad()
            loss.backward()
            nn.utils.clip_grad_norm_(model.parameters(), 1.0)
            opt.step()
            sched.step()
            for k in totals:
                totals[k] += parts[k] * min(cfg.batch_size, p.n_sets - i) / p.n_sets
        history.append({"epoch": epoch + 1, **totals, "seconds": time.perf_counter() - start})
        log.info("epoch %d: nll %.3f kl %.3f pixels %.5f", epoch + 1, totals["nll"], totals["kl"], totals["pixels"])
    return model.eval(), history


@torch.no_grad()
def generate(
    model: PixelVideoModel,
    *,
    context: np.ndarray,
    speeds: np.ndarray,
    sample: int,
    calib_first: np.ndarray | None = None,
    calib_rest: np.ndarray | None = None,
    calib_speed: np.ndarray | None = None,
    seed: int | np.ndarray = 0,
) -> np.ndarray:
    """Sample set ``sample`` of B objects: uint8 frames (B, K, F, H, W, 3) of each object's K pushes.

    context: uint8 (B, K, H, W, 3), each push's first frame; speeds: (K,) m/s; calib_*: the two
    calibration pushes' first and rest frames, uint8 (B, 2, H, W, 3), and speeds (2,) (calibrated
    variant). Sample 0 is the prior's mean (the deterministic use); sample s > 0 draws each object's z
    once from the prior with a generator seeded by (its seed, s), so a set is the same each time it is
    asked, whichever batch its object comes in. seed: one for all objects, or (B,) one per object.
    """
    b, k = context.shape[:2]
    cal = None
    if model.calibrated:
        if calib_first is None or calib_rest is None or calib_speed is None:
            raise ValueError("the calibrated pixel model needs the calibration pushes' frames and speeds")
        cs = torch.as_tensor(np.broadcast_to(calib_speed, (b, 2)).copy(), dtype=torch.float32)
        cal = model.calibration_summary(to_float(calib_first), to_float(calib_rest), cs)
    mu, logvar = model.prior_of(cal, b)
    if sample == 0:
        z = mu
    else:
        seeds = np.broadcast_to(np.asarray(seed, dtype=np.int64), (b,))
        eps = torch.stack(
            [
                torch.randn(mu.shape[1], generator=torch.Generator().manual_seed(int(s) * 1_000_003 + int(sample)))
                for s in seeds
            ]
        )
        z = mu + eps * (0.5 * logvar).exp()
    ls = torch.log(torch.as_tensor(np.broadcast_to(speeds, (b, k)).copy(), dtype=torch.float32)).reshape(-1)
    rep = torch.arange(b).repeat_interleave(k)
    frames, _ = model.render(
        to_float(context.reshape(b * k, *context.shape[2:])), ls, z[rep], cal[rep] if cal is not None else None
    )
    out = to_uint8(frames)
    return out.reshape(b, k, *out.shape[1:])


# -- checkpoints and the imply evaluate interface -------------------------------------------
def save_pixel_video(path: str | os.PathLike, model: PixelVideoModel, history: list[dict]) -> None:
    """Write the model (config, frame shape, weights) and its training history atomically."""
    from imply.io import atomic_path

    payload = {
        "config": model.cfg.to_dict(),
        "calibrated": model.calibrated,
        "frame_shape": tuple(model.background.shape[-2:]),
        "state": model.state_dict(),
        "history": history,
    }
    with atomic_path(path) as tmp:
        torch.save(payload, tmp)


def load_pixel_video(path: str | os.PathLike) -> tuple[PixelVideoModel, list[dict]]:
    """The model :func:`save_pixel_video` wrote, in eval mode, and its history."""
    try:
        payload = torch.load(path, map_location="cpu", weights_only=True)
    except (OSError, RuntimeError, pickle.UnpicklingError) as exc:
        raise ValueError(f"{path}: not a pixel video checkpoint ({exc})") from exc
    if not isinstance(payload, dict) or not {"config", "calibrated", "frame_shape", "state"} <= set(payload):
        raise ValueError(f"{path}: not a pixel video checkpoint (needs config, calibrated, frame_shape and state)")
    cfg = PixelVideoConfig.from_dict(payload["config"], f"{path}: config")
    model = PixelVideoModel(cfg, calibrated=payload["calibrated"], frame_shape=tuple(payload["frame_shape"]))
    model.load_state_dict(payload["state"])
    return model.eval(), list(payload.get("history", []))


class PixelVideoWorldModel:
    """A trained :class:`PixelVideoModel` behind ``imply evaluate``'s interface: kind ``frames``, stochastic.

    ``rollout(request)`` returns the generated frames (B, K, F, H, W, 3) of each query push, the
    last at rest: from each push's first context frame and its speed and, for the calibrated
    variant, the request's calibration clips (first and last frames; own or another object's).
    Sample set ``request.sample`` draws one latent per object (sample 0: the prior's mean).
    """

    kind = "frames"
    stochastic = True

    def __init__(self, model: PixelVideoModel, *, name: str = "pixel_video", batch_size: int = 64, seed: int = 0):
        self.model = model.eval()
        self.name = name
        self.batch_size = int(batch_size)
        self.seed = int(seed)

    def rollout(self, request) -> np.ndarray:
        calibrated = self.model.calibrated
        if calibrated and request.calibration_frames is None:
            raise ValueError(
                f"{self.name} was trained with calibration pushes in context; condition {request.condition!r} "
                "shows none (ask for conditions own and other)"
            )
        cf = request.calibration_frames
        seeds = np.array([zlib.crc32(str(o).encode()) + 7919 * self.seed for o in request.object_ids])
        return generate(
            self.model,
            context=request.context_frames[:, :, 0],
            speeds=request.query_speeds,
            sample=request.sample,
            seed=seeds,
            calib_first=cf[:, :, 0] if calibrated else None,
            calib_rest=cf[:, :, -1] if calibrated else None,
            calib_speed=request.calibration_speeds if calibrated else None,
        )


def trained_pixel_video(
    *, checkpoint: str | os.PathLike, name: str | None = None, batch_size: int | str = 64, seed: int | str = 0
) -> PixelVideoWorldModel:
    """The pixel model trained by ``imply study pixel train`` (``checkpoint``) as an ``imply evaluate`` model::

    imply evaluate --model imply.models.pixel_video:trained_pixel_video,checkpoint=results/pixel/calib/model.pt ...
    """
    model, _ = load_pixel_video(checkpoint)
    if name is None:
        name = "pixel_" + ("calib" if model.calibrated else "nocalib")
    return PixelVideoWorldModel(model, name=name, batch_size=int(batch_size), seed=int(seed))
