"""Measured-style test roads, written as profile files for ISORoad's profile_file: ISO 8608
stretches of different classes joined without a step, and a vertical (sag) curve on top."""
from __future__ import annotations

from pathlib import Path

import numpy as np

from plant import iso8608
from plant.road import SyntheticRoad


def joined_iso(classes: list[int], lengths: list[float], seed: int = 1, dx: float = 0.05) -> tuple[np.ndarray, np.ndarray]:
    """(distance m, elevation m): ISO class classes[i] over lengths[i] m (seed + i), each stretch
    shifted to continue the previous one's level and slope."""
    s_all, h_all = [np.zeros(0)], [np.zeros(0)]
    start = 0.0
    for i, (c, length) in enumerate(zip(classes, lengths)):
        road = SyntheticRoad(iso8608.class_psd_n0(c), seed=seed + i)
        s = np.arange(0.0, length, dx)
        h = np.array([road.height(x) for x in s])
        if len(h_all[-1]) > 1:
            h += h_all[-1][-1] - h[0] + (h_all[-1][-1] - h_all[-1][-2])
        s_all.append(start + s)
        h_all.append(h)
        start += length
    return np.concatenate(s_all), np.concatenate(h_all)


def add_sag(s: np.ndarray, h: np.ndarray, start: float, length: float, depth: float) -> np.ndarray:
    """h plus a smooth vertical sag curve depth (m) deep from start over length (m)."""
    m = (s >= start) & (s <= start + length)
    out = h.copy()
    out[m] -= 0.5 * depth * (1 - np.cos(2 * np.pi * (s[m] - start) / length))
    return out


def write_profile(path: Path | str, s: np.ndarray, h: np.ndarray, level: float = 0.0) -> Path:
    """A CSV profile file (distance_m, elevation_m) with the elevations raised by ``level`` m."""
    path = Path(path)
    path.write_text("distance_m,elevation_m\n" + "".join(f"{u:.3f},{z + level:.7f}\n" for u, z in zip(s, h)))
    return path
