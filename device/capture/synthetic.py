"""Synthetic motion-blurred rope frames with ground truth: the in-process frame source for tests, benchmarks and demos.

A rope of `length_px` pixels hangs from a fixed end and swings as a bending pendulum; a frame is the average of
sub-frames rendered through the exposure (anti-aliased thick polyline), plus Gaussian noise. The ground truth is
the centreline at the start and at the end of each exposure, in the same (u, v) = (col, row) pixel convention as
the pipeline's output. This is not the rig simulator (`ropecam simulate`, host side): it has no camera model, no
physics and no lens; it exists so that the device can be tested and benchmarked on its own.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Iterator
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

__all__ = ["SyntheticFrame", "SyntheticRope"]


@dataclass(frozen=True, slots=True)
class SyntheticFrame:
    """One rendered frame and its truth (points are (u, v) = (col, row) pixels, fixed end first)."""

    index: int
    t_ns: int
    exposure_us: int
    image: NDArray[np.uint8]
    begin_uv: NDArray[np.float64]
    end_uv: NDArray[np.float64]

    @property
    def tip_begin_uv(self) -> NDArray[np.float64]:
        """The free tip at the start of the exposure."""
        return self.begin_uv[-1]

    @property
    def tip_end_uv(self) -> NDArray[np.float64]:
        """The free tip at the end of the exposure."""
        return self.end_uv[-1]


@dataclass(frozen=True, slots=True)
class SyntheticRope:
    """Parameters of the synthetic swinging rope and camera.

    Parameters
    ----------
    width, height
        Image size in pixels.
    fixed_uv
        The fixed end (col, row) in pixels.
    length_px
        Rope length in pixels.
    diameter_px
        Rope diameter in pixels.
    amplitude_rad, period_s
        Swing amplitude (from vertical, towards +u) and period.
    bend
        Extra angle at the tip relative to the fixed end, as a fraction of the swing angle (whip-like bending).
    fps, exposure_us
        Frame rate and exposure time.
    background, rope_level
        Grey levels of background and rope (rope darker than background gives a dark rope).
    noise_dn
        Standard deviation of the Gaussian noise in grey levels.
    phase_rad
        Phase of the swing at t = 0.
    seed
        Noise seed.
    rope_end
        ``flat`` (default: a cut rope or cable, as the rig simulator draws it) or ``round`` (a cap of the rope's
        radius beyond each end of the centreline).
    blur_px
        Gaussian sigma (px) of the camera's blur applied to the exposed image (0: none, the pixel's area only).
    unevenness, unevenness_period_px
        The rope's brightness varies along its length (uneven lighting, a braid's or a dyed rope's pattern): its
        contrast to the background is multiplied by ``1 + unevenness sin(2 pi s / unevenness_period_px)`` at arc
        length s from the fixed end (the pattern moves with the rope). 0: a uniform rope.
    """

    width: int = 320
    height: int = 240
    fixed_uv: tuple[float, float] = (160.3, 20.6)
    length_px: float = 180.0
    diameter_px: float = 4.0
    amplitude_rad: float = 0.6
    period_s: float = 1.2
    bend: float = 0.3
    fps: float = 119.0
    exposure_us: int = 4000
    background: float = 30.0
    rope_level: float = 200.0
    noise_dn: float = 2.0
    phase_rad: float = 0.3
    seed: int = 1
    nodes: int = field(default=64)
    rope_end: str = "flat"
    blur_px: float = 0.0
    unevenness: float = 0.0
    unevenness_period_px: float = 60.0

    def __post_init__(self) -> None:
        if self.rope_end not in ("flat", "round"):
            raise ValueError(f"rope_end must be 'flat' or 'round', got {self.rope_end!r}")
        if not (0.0 <= self.blur_px <= 10.0):
            raise ValueError(f"blur_px must be in [0, 10], got {self.blur_px!r}")
        if not (0.0 <= self.unevenness < 1.0) or not self.unevenness_period_px > 0.0:
            raise ValueError(
                f"unevenness must be in [0, 1) and unevenness_period_px > 0, got {self.unevenness!r} and "
                f"{self.unevenness_period_px!r}"
            )

    def centreline(self, t_s: float) -> NDArray[np.float64]:
        """Return the centreline (nodes, 2) as (u, v) pixels at time `t_s`, fixed end first."""
        omega = 2.0 * math.pi / self.period_s
        theta = self.amplitude_rad * math.cos(omega * t_s + self.phase_rad)
        s = np.linspace(0.0, 1.0, self.nodes)
        phi = theta * (1.0 + self.bend * s)
        ds = self.length_px / (self.nodes - 1)
        du = np.concatenate([[0.0], np.cumsum(0.5 * (np.sin(phi[1:]) + np.sin(phi[:-1])) * ds)])
        dv = np.concatenate([[0.0], np.cumsum(0.5 * (np.cos(phi[1:]) + np.cos(phi[:-1])) * ds)])
        return np.stack([self.fixed_uv[0] + du, self.fixed_uv[1] + dv], axis=1)

    def coverage(self, line_uv: NDArray[np.float64]) -> NDArray[np.float64]:
        """Return the fraction (0-1) of each pixel covered by the rope along `line_uv` (anti-aliased)."""
        return self._cover(line_uv)[0]

    def _cover(self, line_uv: NDArray[np.float64]) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """`coverage`, and the arc length along `line_uv` of each pixel's nearest rope point (0 far from it)."""
        radius = 0.5 * self.diameter_px
        out = np.zeros((self.height, self.width))
        arc_out = np.zeros((self.height, self.width))
        lo = np.floor(line_uv.min(axis=0) - radius - 2).astype(int)
        hi = np.ceil(line_uv.max(axis=0) + radius + 2).astype(int)
        u0, v0 = max(lo[0], 0), max(lo[1], 0)
        u1, v1 = min(hi[0], self.width - 1), min(hi[1], self.height - 1)
        if u1 < u0 or v1 < v0:
            return out, arc_out
        vv, uu = np.mgrid[v0 : v1 + 1, u0 : u1 + 1].astype(np.float64)
        dist = np.full(uu.shape, np.inf)
        arc = np.zeros(uu.shape)
        reach = radius + 2.0
        starts = np.concatenate([[0.0], np.cumsum(np.hypot(*np.diff(line_uv, axis=0).T))])
        for (a, b), start in zip(itertools.pairwise(line_uv), starts, strict=False):
            # Only the pixels near the segment: farther ones get no cover from it whatever their distance (the
            # same numbers where it matters, at a fraction of the work for a long rope).
            c0 = max(math.floor(min(a[0], b[0]) - reach) - u0, 0)
            c1 = min(math.ceil(max(a[0], b[0]) + reach) - u0, u1 - u0) + 1
            r0 = max(math.floor(min(a[1], b[1]) - reach) - v0, 0)
            r1 = min(math.ceil(max(a[1], b[1]) + reach) - v0, v1 - v0) + 1
            if c1 <= c0 or r1 <= r0:
                continue
            uu_s, vv_s, dist_s = uu[r0:r1, c0:c1], vv[r0:r1, c0:c1], dist[r0:r1, c0:c1]
            d = b - a
            t = np.clip(((uu_s - a[0]) * d[0] + (vv_s - a[1]) * d[1]) / max(float(d @ d), 1e-12), 0.0, 1.0)
            here = np.hypot(uu_s - a[0] - t * d[0], vv_s - a[1] - t * d[1])
            if self.unevenness > 0.0:
                nearer = here < dist_s
                arc[r0:r1, c0:c1][nearer] = start + t[nearer] * math.sqrt(float(d @ d))
            np.minimum(dist_s, here, out=dist_s)
        cover = np.clip(radius + 0.5 - dist, 0.0, 1.0)
        if self.rope_end == "flat" and len(line_uv) >= 2:
            # A flat end: beyond the end's plane the rope stops (anti-aliased over one pixel), whatever the
            # distance across; inside it the distance to the polyline is the distance across.
            for end, inner in ((line_uv[-1], line_uv[-2]), (line_uv[0], line_uv[1])):
                t = end - inner
                t = t / max(float(np.hypot(*t)), 1e-12)
                beyond = (uu - end[0]) * t[0] + (vv - end[1]) * t[1]
                across = np.abs((uu - end[0]) * t[1] - (vv - end[1]) * t[0])
                near = np.hypot(uu - end[0], vv - end[1]) <= radius + 2.0  # not other parts of a curled rope
                past = near & (beyond > 0.0)
                cover[past] = np.clip(radius + 0.5 - across[past], 0.0, 1.0)
                cover[near] *= np.clip(0.5 - beyond[near], 0.0, 1.0)
        out[v0 : v1 + 1, u0 : u1 + 1] = cover
        arc_out[v0 : v1 + 1, u0 : u1 + 1] = arc
        return out, arc_out

    def render(self, index: int, rng: np.random.Generator | None = None) -> SyntheticFrame:
        """Render frame `index` (exposure starting at ``index / fps``)."""
        t0 = index / self.fps
        exposure_s = self.exposure_us * 1e-6
        begin = self.centreline(t0)
        end = self.centreline(t0 + exposure_s)
        travel = float(np.max(np.hypot(*(end - begin).T)))
        n_sub = int(min(256, max(4, math.ceil(travel / 0.2))))
        acc = np.zeros((self.height, self.width))
        for k in range(n_sub):
            cover, arc = self._cover(self.centreline(t0 + exposure_s * (k + 0.5) / n_sub))
            if self.unevenness > 0.0:
                cover *= 1.0 + self.unevenness * np.sin(2.0 * math.pi / self.unevenness_period_px * arc)
            acc += cover
        acc /= n_sub
        if self.blur_px > 0.0:
            acc = _gaussian_blur(acc, self.blur_px)
        image = self.background + (self.rope_level - self.background) * acc
        if self.noise_dn > 0:
            rng = rng if rng is not None else np.random.default_rng(self.seed + index)
            image = image + rng.normal(0.0, self.noise_dn, image.shape)
        pixels = np.clip(np.rint(image), 0, 255).astype(np.uint8)
        return SyntheticFrame(index, round(t0 * 1e9), self.exposure_us, pixels, begin, end)

    def frames(self, count: int, start: int = 0) -> Iterator[SyntheticFrame]:
        """Yield `count` consecutive frames starting at frame `start`."""
        for index in range(start, start + count):
            yield self.render(index)


def _gaussian_blur(image: NDArray[np.float64], sigma_px: float) -> NDArray[np.float64]:
    """`image` convolved with a Gaussian of `sigma_px` (separable; the border repeats the edge pixels)."""
    radius = max(1, math.ceil(4.0 * sigma_px))
    taps = np.exp(-0.5 * (np.arange(-radius, radius + 1) / sigma_px) ** 2)
    taps /= taps.sum()
    for axis in (0, 1):
        padded = np.pad(image, [(radius, radius) if a == axis else (0, 0) for a in (0, 1)], mode="edge")
        size = image.shape[axis]
        image = sum(w * np.take(padded, np.arange(k, k + size), axis=axis) for k, w in enumerate(taps))
    return image
