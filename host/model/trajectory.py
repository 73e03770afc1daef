"""A rope's motion as ANCF nodal coordinates over time, evaluated at any material point and any time.

Plane frame (the paper's): x horizontal (the release direction), y along gravity (down), metres, origin at the fixed
end. Nodal coordinates per node are (x, y, x', y') with ' = d/ds along the unstretched arc length s; node k sits at
s = k * L / N. Inside an element the position is the cubic Hermite interpolation of its two nodes, which is exactly
the ANCF cable element's shape; between stored samples in time it is the cubic Hermite interpolation of positions
and velocities, which is fourth-order accurate in the sample spacing.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ropecam.shared.errors import DataError

__all__ = ["DOF_PER_NODE", "Trajectory", "hermite_shape"]

DOF_PER_NODE = 4


def hermite_shape(xi: NDArray[np.float64], element_length_m: float) -> NDArray[np.float64]:
    """Return the four cubic Hermite shape functions at local coordinates `xi` in [0, 1].

    Parameters
    ----------
    xi
        Local coordinates, any shape.
    element_length_m
        Unstretched element length (scales the slope functions).

    Returns
    -------
    ndarray
        Shape ``xi.shape + (4,)``: weights of (r_i, r'_i, r_j, r'_j).
    """
    xi = np.asarray(xi, dtype=np.float64)
    xi2 = xi * xi
    xi3 = xi2 * xi
    return np.stack(
        [
            1.0 - 3.0 * xi2 + 2.0 * xi3,
            element_length_m * (xi - 2.0 * xi2 + xi3),
            3.0 * xi2 - 2.0 * xi3,
            element_length_m * (xi3 - xi2),
        ],
        axis=-1,
    )


@dataclass(frozen=True)
class Trajectory:
    """Nodal coordinates and velocities of an ANCF rope at sample times.

    Parameters
    ----------
    length_m
        Unstretched rope length L.
    times_s
        Sample times, shape (T,), strictly increasing.
    q
        Nodal coordinates, shape (T, 4 (N + 1)), float64, plane frame.
    qdot
        Their time derivatives, same shape.
    energies
        Optional named energy series (J), each of shape (T,).
    """

    length_m: float
    times_s: NDArray[np.float64]
    q: NDArray[np.float64]
    qdot: NDArray[np.float64]
    energies: dict[str, NDArray[np.float64]] = field(default_factory=dict)

    def __post_init__(self) -> None:
        if not (np.isfinite(self.length_m) and self.length_m > 0):
            raise ValueError(f"length_m must be > 0, got {self.length_m!r}")
        t = np.asarray(self.times_s)
        if t.ndim != 1 or t.size < 1:
            raise ValueError(f"times_s must be 1-D and non-empty, got shape {t.shape}")
        if t.size > 1 and not np.all(np.diff(t) > 0):
            raise ValueError("times_s must be strictly increasing")
        for name in ("q", "qdot"):
            a = np.asarray(getattr(self, name))
            if a.ndim != 2 or a.shape[0] != t.size or a.shape[1] % DOF_PER_NODE or a.shape[1] < 2 * DOF_PER_NODE:
                raise ValueError(f"{name} must have shape (T={t.size}, 4 (N + 1)) with N >= 1, got {a.shape}")
        if np.shape(self.q) != np.shape(self.qdot):
            raise ValueError(f"q and qdot shapes differ: {np.shape(self.q)} vs {np.shape(self.qdot)}")

    @property
    def n_elements(self) -> int:
        """Number of elements N."""
        return self.q.shape[1] // DOF_PER_NODE - 1

    @property
    def element_length_m(self) -> float:
        """Unstretched element length L / N."""
        return self.length_m / self.n_elements

    @property
    def duration_s(self) -> float:
        """Time from the first to the last sample."""
        return float(self.times_s[-1] - self.times_s[0])

    def _shape_matrix(self, s_m: NDArray[np.float64]) -> tuple[NDArray[np.intp], NDArray[np.float64]]:
        if np.any(~np.isfinite(s_m)) or np.any(s_m < -1e-12) or np.any(s_m > self.length_m * (1 + 1e-12)):
            raise ValueError(f"arc lengths s_m must lie in [0, {self.length_m}], got {s_m.min()}..{s_m.max()}")
        le = self.element_length_m
        element = np.clip(np.floor(s_m / le).astype(np.intp), 0, self.n_elements - 1)
        xi = np.clip(s_m / le - element, 0.0, 1.0)
        return element, hermite_shape(xi, le)

    def _interpolate(self, coords: NDArray[np.float64], s_m: ArrayLike) -> NDArray[np.float64]:
        """Positions (..., S, 2) at arc lengths from nodal vectors `coords` (..., 4 (N + 1))."""
        s = np.atleast_1d(np.asarray(s_m, dtype=np.float64))
        element, shape = self._shape_matrix(s)
        nodes = coords.reshape(*coords.shape[:-1], self.n_elements + 1, DOF_PER_NODE)
        left = nodes[..., element, :]  # (..., S, 4)
        right = nodes[..., element + 1, :]
        x = shape[:, 0] * left[..., 0] + shape[:, 1] * left[..., 2] + shape[:, 2] * right[..., 0]
        x = x + shape[:, 3] * right[..., 2]
        y = shape[:, 0] * left[..., 1] + shape[:, 1] * left[..., 3] + shape[:, 2] * right[..., 1]
        y = y + shape[:, 3] * right[..., 3]
        return np.stack([x, y], axis=-1)

    def _state_at(self, t_s: ArrayLike) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """Nodal coordinates and velocities at times `t_s` (cubic Hermite in time)."""
        t = np.atleast_1d(np.asarray(t_s, dtype=np.float64))
        t0, t1 = float(self.times_s[0]), float(self.times_s[-1])
        span = max(t1 - t0, 1.0)
        if np.any(~np.isfinite(t)) or np.any(t < t0 - 1e-9 * span) or np.any(t > t1 + 1e-9 * span):
            raise ValueError(f"times must lie in [{t0}, {t1}] s, got {t.min()}..{t.max()}")
        if self.times_s.size == 1:
            return np.repeat(self.q, t.size, axis=0), np.repeat(self.qdot, t.size, axis=0)
        k = np.clip(np.searchsorted(self.times_s, t, side="right") - 1, 0, self.times_s.size - 2)
        h = (self.times_s[k + 1] - self.times_s[k])[:, None]
        u = np.clip((t - self.times_s[k])[:, None] / h, 0.0, 1.0)
        q0, q1, v0, v1 = self.q[k], self.q[k + 1], self.qdot[k], self.qdot[k + 1]
        u2, u3 = u * u, u * u * u
        q = (2 * u3 - 3 * u2 + 1) * q0 + (u3 - 2 * u2 + u) * h * v0 + (-2 * u3 + 3 * u2) * q1 + (u3 - u2) * h * v1
        v = (6 * u2 - 6 * u) / h * q0 + (3 * u2 - 4 * u + 1) * v0 + (-6 * u2 + 6 * u) / h * q1
        v = v + (3 * u2 - 2 * u) * v1
        return q, v

    def positions(self, t_s: ArrayLike, s_m: ArrayLike) -> NDArray[np.float64]:
        """Return positions in metres of material points `s_m` at times `t_s`, shape (len(t), len(s), 2)."""
        q, _ = self._state_at(t_s)
        return self._interpolate(q, s_m)

    def velocities(self, t_s: ArrayLike, s_m: ArrayLike) -> NDArray[np.float64]:
        """Return velocities in m/s of material points `s_m` at times `t_s`, shape (len(t), len(s), 2)."""
        _, v = self._state_at(t_s)
        return self._interpolate(v, s_m)

    def sample_positions(self, s_m: ArrayLike) -> NDArray[np.float64]:
        """Return positions at every stored sample time, shape (T, len(s), 2)."""
        return self._interpolate(self.q, s_m)

    def tip(self) -> NDArray[np.float64]:
        """Return the free tip (s = L) at every stored sample time, shape (T, 2)."""
        return self.sample_positions([self.length_m])[:, 0, :]

    def save(self, path: str | Path) -> None:
        """Write the trajectory to a compressed ``.npz`` file."""
        extra = {f"energy_{k}": v for k, v in self.energies.items()}
        np.savez_compressed(path, length_m=self.length_m, times_s=self.times_s, q=self.q, qdot=self.qdot, **extra)

    @classmethod
    def load(cls, path: str | Path) -> Trajectory:
        """Read a trajectory written by `save`; a bad file raises `DataError` naming it."""
        try:
            with np.load(path) as data:
                energies = {k[len("energy_") :]: data[k] for k in data.files if k.startswith("energy_")}
                return cls(
                    length_m=float(data["length_m"]),
                    times_s=data["times_s"],
                    q=data["q"],
                    qdot=data["qdot"],
                    energies=energies,
                )
        except (OSError, KeyError, ValueError) as exc:
            raise DataError(f"{path}: not a ropecam trajectory file ({exc})") from exc
