"""Measured-style test roads, written as profile files for ISORoad's profile_file: ISO 8608
stretches of different classes joined without a step, vertical curves, grades, an absolute level
and discrete events (a bump, a pothole) on top. ``TEST_ROADS`` names the set the real-road
benchmark and tests drive (docs/real-roads.md)."""
from __future__ import annotations

from pathlib import Path

import numpy as np

from suspension_estimation.plant import iso8608
from suspension_estimation.plant.road import SyntheticRoad


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


def add_bump(s: np.ndarray, h: float | np.ndarray, start: float, length: float, height: float) -> np.ndarray:
    """h plus a half-cosine bump ``height`` m high (negative: a dip) from start over length (m)."""
    m = (s >= start) & (s <= start + length)
    out = np.array(h, float, copy=True)
    out[m] += 0.5 * height * (1 - np.cos(2 * np.pi * (s[m] - start) / length))
    return out


def add_pothole(s: np.ndarray, h: np.ndarray, start: float, length: float, depth: float,
                edge: float = 0.02) -> np.ndarray:
    """h with a pothole ``depth`` m deep from start over length (m): flat bottom, straight edges
    ``edge`` m long (a step the tyre's point contact would otherwise see as infinitely steep)."""
    x = s - start
    d = np.clip(np.minimum(x, length - x) / edge, 0.0, 1.0)
    return h - depth * d


def make_road(name: str, seed: int = 1) -> tuple[np.ndarray, np.ndarray]:
    """(distance m, elevation m) of the test road ``name`` (one of TEST_ROADS), ISO seed ``seed``."""
    if name == "sag":  # ISO A 300 m joined to ISO C 400 m, a 1.1 m sag over 250 m
        s, h = joined_iso([1, 3], [300.0, 400.0], seed)
        return s, add_sag(s, h, 200.0, 250.0, 1.1)
    s, h = joined_iso([2], [800.0 if name == "curves" else 600.0], seed)
    if name == "curves":  # sags of 2 m over 300 m and 1 m over 150 m, a 0.5 m crest over 100 m
        h = add_sag(s, h, 100.0, 300.0, 2.0)
        h = add_sag(s, h, 450.0, 100.0, -0.5)
        return s, add_sag(s, h, 600.0, 150.0, 1.0)
    if name == "grade":  # a constant 3 % grade from the start
        return s, h + 0.03 * s
    if name == "level":  # the road 583 m above the datum
        return s, h + 583.0
    if name == "bump":  # a 30 mm bump, 0.5 m long, at 300 m
        return s, add_bump(s, h, 300.0, 0.5, 0.03)
    if name == "pothole":  # a 30 mm deep pothole, 0.4 m long, at 300 m
        return s, add_pothole(s, h, 300.0, 0.4, 0.03)
    if name == "iso_a":  # a smooth road: ISO A, 600 m
        s, h = joined_iso([1], [600.0], seed)
        return s, h
    raise ValueError(f"unknown test road {name!r}; one of {', '.join(TEST_ROADS)}")


TEST_ROADS = {
    "sag": "ISO A 300 m joined to ISO C 400 m, a 1.1 m sag over 250 m from 200 m",
    "curves": "ISO B 800 m, sags of 2 m / 300 m (at 100 m) and 1 m / 150 m (at 600 m), a 0.5 m / 100 m crest (at 450 m)",
    "grade": "ISO B 600 m on a constant 3 % grade",
    "level": "ISO B 600 m at 583 m above the datum",
    "bump": "ISO B 600 m, a 30 mm half-cosine bump 0.5 m long at 300 m",
    "pothole": "ISO B 600 m, a 30 mm deep pothole 0.4 m long (2 cm edges) at 300 m",
    "iso_a": "ISO A 600 m (smooth)",
}
