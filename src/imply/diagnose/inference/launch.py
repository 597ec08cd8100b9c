"""The launch left free: each condition's launch profiled out of every fit, so that only the slide reads the effects.

The contact between pusher and box, and the box's compliance on the table, decide how fast the box
leaves the pusher (the launch); what slows it afterwards decides the slide. :class:`FreeLaunch` is the
part of :class:`imply.diagnose.inference.fit.Problem` that frees the launch: it reads the problem's conditions and
rows (``cond``, ``t_cond``, ``t_kind``, ``n_cond``), their sds and weights (``sd_d``, ``sd_t``, ``w_d``,
``w_t``) and predicts with :meth:`imply.diagnose.physics.prediction.Predicting.predict_at`.
"""

from __future__ import annotations

from dataclasses import replace
from functools import cached_property
from typing import Self

import numpy as np

from imply.diagnose.physics.candidates import Model
from imply.diagnose.physics.prediction import ObjectFit


class FreeLaunch:
    """Freeing each condition's launch (a mixin of :class:`imply.diagnose.inference.fit.Problem`; its ``launch`` field holds
    the directions once freed)."""

    def with_free_launch(self, objects: ObjectFit) -> Self:
        """The launch freed: each condition (an object at a speed and direction) may leave the pusher at a speed of
        its own, a nuisance every fit profiles out, so that only what the slide shows (the displacement against the
        stop time, and the track) reads the effects. The contact decides the launch, the slide's physics decides
        the rest. Linearised once, at ``objects`` under the table alone: the direction along which a condition's
        predictions move with the log of the speed the box is launched at. Without an observable beside the
        displacement nothing would be left, and the problem is returned as it is."""
        if not self.use_t:
            return self
        h = 0.01
        lm, lu = objects.lm[self.c_obj], objects.lu[self.c_obj]
        up = self.predict_at(Model(), np.zeros(0), self.c_v * np.exp(h), self.c_phi, lm, lu)
        down = self.predict_at(Model(), np.zeros(0), self.c_v * np.exp(-h), self.c_phi, lm, lu)
        jd = (up.log_d - down.log_d) / (2 * h)
        jt = (up.log_t - down.log_t) / (2 * h)
        return replace(self, launch=np.column_stack([jd, jt]))

    @cached_property
    def _launch_rows(self) -> tuple[np.ndarray, np.ndarray]:
        """(m,) the condition of each push and aux row, and (m,) its whitened launch direction (unweighted)."""
        cond, j = [self.cond], [self.launch[self.cond, 0] / self.sd_d]
        if self.use_t:
            cond.append(self.t_cond)
            j.append(self.launch[self.t_cond, 1 + self.t_kind] / self.sd_t)
        return np.concatenate(cond), np.concatenate(j)

    @cached_property
    def _row_weights(self) -> np.ndarray:
        """(m,) each push and aux row's weight."""
        return np.concatenate([self.w_d, self.w_t]) if self.use_t else self.w_d

    def _free_launch(self, r: np.ndarray, *, weighted: bool = True) -> np.ndarray:
        """Whitened residuals (K, m) of the pushes and aux rows with each condition's launch profiled out: the part
        along the condition's launch direction, fitted on the rows that count, taken away. ``weighted``: the rows
        are already weighted (as :meth:`residuals` gives them); else they are not, and a row left out keeps its
        residual less the launch its condition's other rows fit."""
        cond, j = self._launch_rows
        w = self._row_weights
        jw = j * w
        rw = r if weighted else r * w
        k, c = r.shape[0], self.n_cond
        idx = (np.arange(k)[:, None] * c + cond[None, :]).ravel()
        num = np.bincount(idx, (rw * jw).ravel(), minlength=k * c).reshape(k, c)
        den = np.bincount(cond, jw * jw, minlength=c)
        lam = np.where(den > 0, num / np.maximum(den, 1e-300), 0.0)
        return r - lam[:, cond] * (jw if weighted else j)

    @property
    def n_nuisance(self) -> int:
        """Parameters every fit profiles out beside the objects' own: one launch per condition where freed."""
        return self.n_cond if self.launch is not None else 0
