"""Colour scales of the distortion outputs and their legends (no bpy): values -> linear RGBA,
ranges chosen from the data (a percentile), the stops a legend draws."""
import numpy as np


def _srgb_to_linear(c):
    c = np.asarray(c, dtype=np.float64)
    return np.where(c <= 0.04045, c / 12.92, ((c + 0.055) / 1.055) ** 2.4)


# display (sRGB) stops: a viridis-like sequential scale and a blue-white-red diverging one
SEQUENTIAL = np.array([[0.267, 0.005, 0.329], [0.230, 0.322, 0.546], [0.128, 0.567, 0.551],
                       [0.369, 0.789, 0.383], [0.993, 0.906, 0.144]])
DIVERGING = np.array([[0.230, 0.299, 0.754], [0.552, 0.690, 0.996], [0.866, 0.866, 0.866],
                      [0.958, 0.604, 0.482], [0.706, 0.016, 0.150]])
INVALID = (1.0, 0.0, 1.0)  # magenta: flipped or degenerate


def colour_scale(values, lo, hi, stops=SEQUENTIAL):
    """Linear RGBA (n,4) of values on the scale [lo, hi] (clamped); non-finite -> magenta."""
    v = np.asarray(values, dtype=np.float64)
    t = (v - lo) / (hi - lo) if hi > lo else np.zeros_like(v)
    t = np.clip(np.nan_to_num(t, nan=0.0, posinf=1.0, neginf=0.0), 0.0, 1.0)
    x = t * (len(stops) - 1)
    i = np.minimum(x.astype(np.int64), len(stops) - 2)
    f = (x - i)[:, None]
    rgb = stops[i] * (1 - f) + stops[i + 1] * f
    rgb[~np.isfinite(v)] = INVALID
    out = np.ones((len(v), 4))
    out[:, :3] = _srgb_to_linear(rgb)
    return out


def robust_range(values, lo_q=0.0, hi_q=0.99, floor=None):
    v = np.asarray(values, dtype=np.float64)
    v = v[np.isfinite(v)]
    if len(v) == 0:
        return (0.0, 1.0)
    lo = float(np.quantile(v, lo_q)) if floor is None else float(floor)
    hi = float(np.quantile(v, hi_q))
    if hi <= lo:
        hi = lo + 1e-6
    return lo, hi


def symmetric_range(values, q=0.99):
    v = np.asarray(values, dtype=np.float64)
    v = np.abs(v[np.isfinite(v)])
    m = float(np.quantile(v, q)) if len(v) else 1.0
    m = m if m > 0 else 1e-6
    return -m, m


STOPS = {"SEQUENTIAL": SEQUENTIAL, "DIVERGING": DIVERGING}


def legend_stops(scale, lo, hi, ticks=5):
    """What a legend draws for a colour scale on [lo, hi]: (colours (k,3) display sRGB of the
    scale's stops, tick values (ticks,), the tick labels formatted to read at a glance)."""
    values = np.linspace(lo, hi, ticks)
    return np.asarray(STOPS[scale]), values, [format_tick(v) for v in values]


def format_tick(v):
    """A legend number in at most 5 characters where possible: 1.25, 12.5, 1e-04, -0.3."""
    a = abs(v)
    if a == 0:
        return "0"
    if a >= 1e4 or a < 1e-2:
        return f"{v:.0e}"
    return f"{v:.3g}"
