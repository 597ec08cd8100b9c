"""What a robot records beside the displacement: the pusher's mean speed and summaries of the box's track.

A push's track is the box's travel along the push over time, x(t), from the start of the
push (t = 0, the pusher at rest against the box) until the box stops at the displacement
d. The diagnostic compares three kinds of summary with the simulator's:

- the pusher's mean speed over the stroke (stroke length over stroke time), which the
  servo's encoders give; a velocity servo does not reach its command within a short
  stroke, and a heavy box slows it, so it is compared with the simulator's prediction for
  the same command, box and friction, never with the command;
- the times at which the box has covered given fractions of its final displacement
  (:data:`FRACTIONS`), read off the track by interpolation. Beside the stop time they
  give the track's shape: a Coulomb slide decelerates uniformly, a viscous one
  exponentially, quadratic drag most while fast, and a speed error changes how fast the
  box leaves the pusher but not how it slows.

Times are taken from the track's running maximum, so camera noise around a stopped box
does not move a crossing backward; the crossing is interpolated between frames.
"""

from __future__ import annotations

import numpy as np

# fractions of the final displacement whose crossing times summarise a track
FRACTIONS = (0.25, 0.5, 0.75)
# a push's stop time: when the box's speed in the table plane falls below this (m/s), read from its
# positions recorded every FRAME_STEP (s) for at most STOP_HORIZON (s) from the start of the push
STOP_SPEED = 0.01
FRAME_STEP = 0.001
STOP_HORIZON = 2.5
# a filmed push's track is cut this long (s) after its box stops
TRACK_AFTER_STOP = 0.1


def stop_frame_times(end: float = STOP_HORIZON) -> np.ndarray:
    """(T,) the times (s from the start of a push) at which the box is recorded to find its stop time."""
    return np.arange(0.0, end + FRAME_STEP / 2, FRAME_STEP)


def track_frame_times(rate: float) -> np.ndarray:
    """(T,) a camera's frame times (s from the start of a push) at ``rate`` frames per second, up to the horizon."""
    return np.arange(0.0, STOP_HORIZON, 1.0 / rate)


def filmed(times: np.ndarray, stop_time: float) -> np.ndarray:
    """(T,) which frames at ``times`` a push's track keeps: up to :data:`TRACK_AFTER_STOP` after the box stopped
    (every frame where it never stopped, NaN)."""
    times = np.asarray(times, float)
    return times <= stop_time + TRACK_AFTER_STOP if np.isfinite(stop_time) else np.ones(times.size, bool)


def yaw_of(quat: np.ndarray) -> np.ndarray:
    """Yaw (rad) of unit quaternions (..., 4), w first: the rotation about the vertical."""
    w, x, y, z = (quat[..., i] for i in range(4))
    return np.arctan2(2.0 * (w * z + x * y), 1.0 - 2.0 * (y * y + z * z))


def crossing_times(times: np.ndarray, travel: np.ndarray, displacement: np.ndarray, fractions=FRACTIONS) -> np.ndarray:
    """When each track first covers each fraction of its displacement.

    Args:
      times: (n, T) or (T,) frame times (s), increasing along each row.
      travel: (n, T) the box's travel along the push at those times (m).
      displacement: (n,) the final displacement the fractions are of (m).
      fractions: (Q,) in (0, 1).

    Returns (n, Q) times (s); NaN where a track never covers the fraction.
    """
    travel = np.atleast_2d(np.asarray(travel, float))
    times = np.broadcast_to(np.asarray(times, float), travel.shape)
    n, _ = travel.shape
    reach = np.maximum.accumulate(travel, axis=1)
    d = np.asarray(displacement, float).reshape(n)
    out = np.full((n, len(fractions)), np.nan)
    rows = np.arange(n)
    for j, q in enumerate(fractions):
        level = q * d
        above = reach >= level[:, None]
        k = np.argmax(above, axis=1)
        has = above[rows, k] & (k > 0)
        i = rows[has]
        k = k[has]
        x0, x1 = reach[i, k - 1], reach[i, k]
        t0, t1 = times[i, k - 1], times[i, k]
        w = np.where(x1 > x0, (level[i] - x0) / np.where(x1 > x0, x1 - x0, 1.0), 1.0)
        out[i, j] = t0 + w * (t1 - t0)
        # a track already past the fraction at its first frame crossed it at that frame
        first = above[:, 0]
        out[first, j] = times[first, 0]
    return out


def pusher_speed(stroke: float, stroke_time: np.ndarray) -> np.ndarray:
    """The pusher's mean speed over the stroke (m/s): stroke length (m) over stroke time (s), (n,)."""
    st = np.asarray(stroke_time, float)
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.where(st > 0, stroke / st, np.nan)


def stop_times(frames_xy: np.ndarray, frames_time: np.ndarray, threshold: float = STOP_SPEED) -> np.ndarray:
    """When each push's speed in the plane first falls below ``threshold`` after it has exceeded it.

    frames_xy: (n, T, 2) box positions at times frames_time (n, T). Speeds are taken
    between successive frames (at their mid-times) and the crossing is interpolated.
    """
    dt = np.diff(frames_time, axis=1)
    dist = np.linalg.norm(np.diff(frames_xy, axis=1), axis=2)
    valid = dt > 1e-9  # two frames taken at one step carry no speed: use the previous one's
    with np.errstate(divide="ignore", invalid="ignore"):
        speed = np.where(valid, dist / np.where(valid, dt, 1.0), 0.0)
    mid = 0.5 * (frames_time[:, 1:] + frames_time[:, :-1])
    n, k = speed.shape
    last = np.maximum.accumulate(np.where(valid, np.arange(k)[None, :], 0), axis=1)
    rows = np.arange(n)[:, None]
    speed, mid = speed[rows, last], mid[rows, last]
    out = np.full(n, np.nan)
    moving = np.maximum.accumulate(speed >= threshold, axis=1)
    below = (speed < threshold) & moving
    first = np.argmax(below, axis=1)
    has = below[np.arange(n), first]
    for i in np.flatnonzero(has):
        j = first[i]
        s0, s1 = speed[i, j - 1], speed[i, j]
        w = (s0 - threshold) / (s0 - s1) if s0 > s1 else 1.0
        out[i] = mid[i, j - 1] + w * (mid[i, j] - mid[i, j - 1])
    return out
