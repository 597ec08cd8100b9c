"""A small action-conditioned, stochastic video model in pixel space: the push's frames from its first one.

The family is stochastic variational video prediction with a dynamic-neural-advection
decoder (CDNA: Finn, Goodfellow and Levine 2016; its stochastic form SV2P: Babaeizadeh
et al. 2018), cut down to a fixed camera and one moving object so that it trains on two
CPU cores:

- **advection**: each generated frame is the table (a learned image per frame index,
  the pusher included) with the box composited on top: the context frame's box (a
  learned soft mask of it) moved along the push by a 1-D convolution kernel, a softmax
  over whole-pixel shifts 0 .. ``max_shift`` - 1. The kernel is what the dynamics
  predict; its mean is the slide in pixels, so the generated box is one blob of the
  context box's size, never a smear across the frame;
- **dynamics**: an MLP from the context frame's features, the commanded speed (log), the
  frame's index and a latent ``z`` (and, in the calibrated variant, the two calibration
  pushes: their first and rest frames' features and their speeds) to the kernel's logits;
- **stochastic**: ``z`` is drawn once per sample set (one object, all K query speeds), so
  a set describes one hypothetical object and sets differ in the object they imagine.
  Its prior is N(0, I) without calibration and a Gaussian read from the calibration
  pushes with it; training maximises the evidence lower bound with a posterior that sees
  the set's true frames (every push of one object shares one ``z``).

Shapes: frames are uint8 (..., H, W, 3) at the interface and float (..., 3, H, W) in
[0, 1] inside. :class:`PixelVideoModel` is the network; :func:`train_pixel_video` fits it
on a clip split (:func:`imply.data.clips.load_clips`); :func:`generate` draws sample sets.
"""

from __future__ import annotations

import logging
import math
import warnings
from dataclasses import dataclass

import numpy as np
import pandas as pd
import torch
import torch.nn.functional as F
from torch import nn
from tqdm.auto import tqdm

log = logging.getLogger("imply.models.pixel_video")


@dataclass(frozen=True, kw_only=True)
class PixelVideoConfig:
    """The network's size and the training recipe."""

    calibrated: bool = True  # condition on the object's two calibration pushes
    width: int = 32  # conv channels and MLP width
    latent: int = 4  # z per sample set
    max_shift: int = 56  # pixels (the longest slide of the training clips is 49 px at 1 cm per pixel)
    frames: tuple[int, ...] = (1, 4, 7)  # future frame indices generated (7: at rest)
    beta: float = 1e-3  # weight of the KL term per pixel-mean squared error unit
    profile_weight: float = 30.0  # weight of the column-profile error beside the pixel error (frame_loss)
    epochs: int = 30
    batch_size: int = 32
    lr: float = 2e-3
    seed: int = 0
    threads: int = 2


def to_float(frames: np.ndarray | torch.Tensor) -> torch.Tensor:
    """uint8 (..., H, W, 3) -> float (..., 3, H, W) in [0, 1]."""
    x = torch.as_tensor(np.asarray(frames))
    return x.movedim(-1, -3).float() / 255.0


def to_uint8(x: torch.Tensor) -> np.ndarray:
    """float (..., 3, H, W) in [0, 1] -> uint8 (..., H, W, 3)."""
    return (x.clamp(0, 1) * 255.0).round().to(torch.uint8).movedim(-3, -1).numpy()


class FrameFeatures(nn.Module):
    """A frame (B, 3, H, W) -> features (B, width): three strided convolutions and a mean over the image."""

    def __init__(self, width: int) -> None:
        super().__init__()
        self.net = nn.Sequential(
            nn.Conv2d(3, width, 3, stride=2, padding=1), nn.GELU(),
            nn.Conv2d(width, width, 3, stride=2, padding=1), nn.GELU(),
            nn.Conv2d(width, width, 3, stride=2, padding=1), nn.GELU(),
        )  # fmt: skip
        # the box's column matters, not only what it looks like: a column-weighted pooling beside the mean
        self.out = nn.Linear(2 * width, width)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        h = self.net(x)
        cols = torch.linspace(-1, 1, h.shape[-1], device=h.device)
        pooled = torch.cat([h.mean((-2, -1)), (h.mean(-2) * cols).mean(-1)], -1)
        return self.out(pooled)


def shift_right(x: torch.Tensor, kernel: torch.Tensor) -> torch.Tensor:
    """``x`` (B, C, H, W) moved along W by the shift distribution ``kernel`` (B, S): sum_s kernel[s] x shifted s."""
    s = kernel.shape[-1]
    padded = F.pad(x, (s - 1, 0))  # zeros enter from the left
    # stack of the S shifted copies: shift s is columns [S-1-s, S-1-s+W) of the padded image
    w = x.shape[-1]
    copies = torch.stack([padded[..., s - 1 - k : s - 1 - k + w] for k in range(s)], 1)  # (B, S, C, H, W)
    return torch.einsum("bs,bschw->bchw", kernel, copies)


class PixelVideoModel(nn.Module):
    """The network: features, masks, the table per frame index, the latent's prior and posterior, the dynamics."""

    def __init__(self, cfg: PixelVideoConfig, *, frame_shape: tuple[int, int], background: np.ndarray | None = None):
        super().__init__()
        self.cfg = cfg
        h, w = frame_shape
        n_f = len(cfg.frames)
        self.features = FrameFeatures(cfg.width)
        self.mask_net = nn.Sequential(nn.Conv2d(3, 8, 3, padding=1), nn.GELU(), nn.Conv2d(8, 1, 3, padding=1))
        nn.init.zeros_(self.mask_net[-1].weight)
        nn.init.zeros_(self.mask_net[-1].bias)
        # the box is the red thing on a grey table: the mask starts as a steep function of red minus green (the
        # frame readout's saliency) and the network learns what to change; from a uniform start it never found it
        self.mask_gain = nn.Parameter(torch.tensor(40.0))
        self.mask_bias = nn.Parameter(torch.tensor(-4.0))
        bg = torch.full((n_f, 3, h, w), 0.33) if background is None else to_float(background)
        self.background = nn.Parameter(bg.clone())
        cal = 2 * (2 * cfg.width + 2) if cfg.calibrated else 0
        self.calibration = nn.Sequential(nn.Linear(cal, cfg.width), nn.GELU()) if cfg.calibrated else None
        c = cfg.width if cfg.calibrated else 0
        self.prior = nn.Linear(c, 2 * cfg.latent) if cfg.calibrated else None
        # posterior: the set's context and rest frames' features, speeds, and the calibration's summary
        self.posterior = nn.Sequential(nn.Linear(2 * cfg.width + 1 + c, cfg.width), nn.GELU(),
                                       nn.Linear(cfg.width, 2 * cfg.latent))  # fmt: skip
        self.dynamics = nn.Sequential(
            nn.Linear(cfg.width + 1 + cfg.latent + c, 2 * cfg.width), nn.GELU(),
            nn.Linear(2 * cfg.width, 2 * cfg.width), nn.GELU(), nn.Linear(2 * cfg.width, n_f * cfg.max_shift),
        )  # fmt: skip

    # -- pieces -------------------------------------------------------------------------
    def mask(self, frame: torch.Tensor) -> torch.Tensor:
        """The box's soft mask (N, 1, H, W) in frames (N, 3, H, W)."""
        red = (frame[:, :1] - frame[:, 1:2]).clamp(min=0)
        return torch.sigmoid(self.mask_net(frame) + self.mask_gain * red + self.mask_bias)

    def calibration_summary(self, calib_first, calib_rest, calib_speed) -> torch.Tensor | None:
        """(B, 2, 3, H, W) first and rest frames of the two calibration pushes, (B, 2) speeds -> (B, width)."""
        if self.calibration is None:
            return None
        b = calib_first.shape[0]
        first, rest = calib_first.flatten(0, 1), calib_rest.flatten(0, 1)
        f0 = self.features(first).view(b, 2, -1)
        f1 = self.features(rest).view(b, 2, -1)
        # how far the box went, as the model's own mask sees it: a keypoint, not a label
        slide = (self.column(rest) - self.column(first)).clamp(min=0).view(b, 2, 1)
        x = torch.cat([f0, f1 - f0, torch.log(calib_speed).unsqueeze(-1), torch.log1p(slide)], -1).flatten(1)
        return self.calibration(x)

    def column(self, frame: torch.Tensor) -> torch.Tensor:
        """The box's column (N,) in frames (N, 3, H, W): the centroid of its mask along the push, in pixels."""
        m = self.mask(frame).sum(-2).squeeze(1)  # (N, W)
        cols = torch.arange(m.shape[-1], dtype=m.dtype)
        return (m * cols).sum(-1) / m.sum(-1).clamp(min=1e-6)

    def prior_of(self, cal: torch.Tensor | None, b: int) -> tuple[torch.Tensor, torch.Tensor]:
        if self.prior is None:
            z = torch.zeros(b, self.cfg.latent)
            return z, z
        mu, logvar = self.prior(cal).chunk(2, -1)
        return mu, logvar.clamp(-8, 4)

    def posterior_of(self, ctx_feat, rest_feat, log_speed, cal, set_index, n_sets):
        """Per push features (N, ...) pooled per set (``set_index`` (N,) in 0 .. n_sets - 1) -> (n_sets, latent) x 2."""
        x = torch.cat([ctx_feat, rest_feat - ctx_feat, log_speed.unsqueeze(-1)], -1)
        pooled = torch.zeros(n_sets, x.shape[-1]).index_add_(0, set_index, x)
        pooled = pooled / torch.bincount(set_index, minlength=n_sets).clamp(min=1).unsqueeze(-1)
        if cal is not None:
            pooled = torch.cat([pooled, cal], -1)
        mu, logvar = self.posterior(pooled).chunk(2, -1)
        return mu, logvar.clamp(-8, 4)

    def render(self, context: torch.Tensor, log_speed: torch.Tensor, z: torch.Tensor, cal: torch.Tensor | None,
               *, features: torch.Tensor | None = None):  # fmt: skip
        """Frames (N, F, 3, H, W) generated from context frames (N, 3, H, W), log speeds (N,), latents (N, latent)
        and calibration summaries (N, width) or None; and the shift kernels (N, F, S). ``features``: the context
        frames' features where the caller has them already."""
        feat = self.features(context) if features is None else features
        parts = [feat, log_speed.unsqueeze(-1), z] + ([cal] if cal is not None else [])
        logits = self.dynamics(torch.cat(parts, -1)).view(len(context), len(self.cfg.frames), self.cfg.max_shift)
        kernel = logits.softmax(-1)
        m = self.mask(context)  # (N, 1, H, W): the box
        box = torch.cat([context * m, m], 1)
        frames = []
        for f in range(kernel.shape[1]):
            moved = shift_right(box, kernel[:, f])
            rgb, alpha = moved[:, :3], moved[:, 3:].clamp(0, 1)
            frames.append(self.background[f] * (1 - alpha) + rgb)
        return torch.stack(frames, 1), kernel


# -- data -----------------------------------------------------------------------------------
@dataclass(frozen=True)
class Pushes:
    """The training pushes of a clip split, grouped into sets (one per object): tensors on the CPU.

    context: (N, 3, H, W) first frames; target: (N, F, 3, H, W) the frames to generate;
    log_speed: (N,); set_index: (N,) the object of each push; calib_first, calib_rest: (n_sets, 2, 3, H, W);
    calib_speed: (n_sets, 2).
    """

    context: torch.Tensor
    target: torch.Tensor
    log_speed: torch.Tensor
    set_index: torch.Tensor
    calib_first: torch.Tensor
    calib_rest: torch.Tensor
    calib_speed: torch.Tensor

    @property
    def n_sets(self) -> int:
        return int(self.calib_speed.shape[0])


def training_pushes(frames: np.ndarray, meta: pd.DataFrame, cfg: PixelVideoConfig) -> Pushes:
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
    rows = meta.index[meta["role"] == "query"].to_numpy() if cfg.calibrated else meta.index.to_numpy()
    fr = list(cfg.frames)
    return Pushes(
        context=to_float(frames[rows, 0]), target=to_float(frames[rows][:, fr]),
        log_speed=torch.as_tensor(np.log(meta["speed"].to_numpy()[rows]), dtype=torch.float32),
        set_index=torch.as_tensor([order[o] for o in objs[rows]]),
        calib_first=to_float(frames[cal, 0]), calib_rest=to_float(frames[cal, -1]),
        calib_speed=torch.as_tensor(meta["speed"].to_numpy()[cal], dtype=torch.float32),
    )  # fmt: skip


def frame_loss(gen: torch.Tensor, target: torch.Tensor, *, profile_weight: float, scales: tuple[int, ...] = (1, 4, 16)
               ) -> torch.Tensor:  # fmt: skip
    """Pixel mean squared error, plus ``profile_weight`` times that of the frames' column profiles (each column's
    mean over the rows) averaged over 1, 4 and 16 columns. A box of a few pixels is a sliver of the frame's
    squared error, and one generated far from where it is shares no pixel with it; its column profile shows
    how far it slid at every scale."""
    g, t = gen.flatten(0, 1), target.flatten(0, 1)
    pg, pt = g.mean(-2, keepdim=True), t.mean(-2, keepdim=True)
    profile = sum(F.mse_loss(F.avg_pool2d(pg, (1, k)), F.avg_pool2d(pt, (1, k))) for k in scales) / len(scales)
    return F.mse_loss(g, t) + profile_weight * profile


def elbo_loss(model: PixelVideoModel, p: Pushes, sets: torch.Tensor) -> tuple[torch.Tensor, dict]:
    """Negative ELBO of the pushes of ``sets`` (indices into p's sets): pixel MSE (mean) + beta KL per set."""
    pick = torch.isin(p.set_index, sets)
    remap = torch.full((p.n_sets,), -1, dtype=torch.long)
    remap[sets] = torch.arange(len(sets))
    idx = remap[p.set_index[pick]]
    cal = model.calibration_summary(p.calib_first[sets], p.calib_rest[sets], p.calib_speed[sets])
    ctx, tgt, ls = p.context[pick], p.target[pick], p.log_speed[pick]
    ctx_f, rest_f = model.features(ctx), model.features(tgt[:, -1])
    mu_q, lv_q = model.posterior_of(ctx_f, rest_f, ls, cal, idx, len(sets))
    mu_p, lv_p = model.prior_of(cal, len(sets))
    z = mu_q + torch.randn_like(mu_q) * (0.5 * lv_q).exp()
    gen, _ = model.render(ctx, ls, z[idx], cal[idx] if cal is not None else None, features=ctx_f)
    mse = frame_loss(gen, tgt, profile_weight=model.cfg.profile_weight)
    kl = 0.5 * (lv_p - lv_q + ((lv_q.exp() + (mu_q - mu_p) ** 2) / lv_p.exp()) - 1).sum(-1).mean()
    return mse + model.cfg.beta * kl, {"mse": float(mse.detach()), "kl": float(kl.detach())}


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


def train_pixel_video(frames: np.ndarray, meta: pd.DataFrame, cfg: PixelVideoConfig) -> tuple[PixelVideoModel, list]:
    """Fit the model on a clip split (uint8 frames (N, T, H, W, 3) and its metadata); returns it and the history."""
    torch.manual_seed(cfg.seed)
    torch.set_num_threads(cfg.threads)
    p = training_pushes(frames, meta, cfg)
    bg = empty_table(frames[:: max(1, len(frames) // 400)][:, list(cfg.frames)])
    model = PixelVideoModel(cfg, frame_shape=frames.shape[2:4], background=bg)
    opt = torch.optim.AdamW(model.parameters(), lr=cfg.lr, weight_decay=1e-4)
    steps = cfg.epochs * math.ceil(p.n_sets / cfg.batch_size)
    sched = torch.optim.lr_scheduler.OneCycleLR(opt, max_lr=cfg.lr, total_steps=steps, pct_start=0.1)
    gen = torch.Generator().manual_seed(cfg.seed)
    history = []
    for epoch in tqdm(range(cfg.epochs), desc="pixel video model", unit="epoch"):
        perm = torch.randperm(p.n_sets, generator=gen)
        totals = {"mse": 0.0, "kl": 0.0}
        for i in range(0, p.n_sets, cfg.batch_size):
            loss, parts = elbo_loss(model, p, perm[i : i + cfg.batch_size])
            opt.zero_grad()
            loss.backward()
            nn.utils.clip_grad_norm_(model.parameters(), 1.0)
            opt.step()
            sched.step()
            for k in totals:
                totals[k] += parts[k] * min(cfg.batch_size, p.n_sets - i) / p.n_sets
        history.append({"epoch": epoch + 1, **totals})
        log.info("epoch %d: mse %.5f kl %.3f", epoch + 1, totals["mse"], totals["kl"])
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
    seed: int = 0,
) -> np.ndarray:
    """Sample set ``sample`` of B objects: uint8 frames (B, K, F, H, W, 3) of each object's K pushes.

    context: uint8 (B, K, H, W, 3), each push's first frame; speeds: (K,) m/s; calib_*: the two
    calibration pushes' first and rest frames, uint8 (B, 2, H, W, 3), and speeds (2,) (calibrated
    variant). Sample 0 is the prior's mean (the deterministic use); sample s > 0 draws z once per
    object from the prior with a generator seeded by (seed, s), the same set each time it is asked.
    """
    b, k = context.shape[:2]
    cal = None
    if model.cfg.calibrated:
        if calib_first is None or calib_rest is None or calib_speed is None:
            raise ValueError("the calibrated pixel model needs the calibration pushes' frames and speeds")
        cs = torch.as_tensor(np.broadcast_to(calib_speed, (b, 2)).copy(), dtype=torch.float32)
        cal = model.calibration_summary(to_float(calib_first), to_float(calib_rest), cs)
    mu, logvar = model.prior_of(cal, b)
    if sample == 0:
        z = mu
    else:
        g = torch.Generator().manual_seed(int(seed) * 1_000_003 + int(sample))
        z = mu + torch.randn(mu.shape, generator=g) * (0.5 * logvar).exp()
    ls = torch.log(torch.as_tensor(np.broadcast_to(speeds, (b, k)).copy(), dtype=torch.float32)).reshape(-1)
    rep = torch.arange(b).repeat_interleave(k)
    frames, _ = model.render(to_float(context.reshape(b * k, *context.shape[2:])), ls, z[rep],
                             cal[rep] if cal is not None else None)  # fmt: skip
    out = to_uint8(frames)
    return out.reshape(b, k, *out.shape[1:])
