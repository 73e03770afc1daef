"""Configuration of the ANCF rope model: the rope and its environment, and the time integrator.

Plane frame: x horizontal, y along gravity (down), metres, origin at the fixed end.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Literal

from ropecam.shared.config import check_finite, check_positive, check_range

__all__ = ["FixedEndMotion", "RopeConfig", "SolverConfig"]


@dataclass(frozen=True, slots=True)
class FixedEndMotion:
    """Prescribed sinusoidal motion of the fixed end: ``r0(t) = amplitude_m * sin(2 pi f t + phase)``.

    All zero (the default) keeps the fixed end at the origin.
    """

    amplitude_x_m: float = 0.0
    amplitude_y_m: float = 0.0
    frequency_hz: float = 0.0
    phase_rad: float = 0.0

    def __post_init__(self) -> None:
        for name in ("amplitude_x_m", "amplitude_y_m", "phase_rad"):
            check_finite(name, getattr(self, name))
        check_range("frequency_hz", self.frequency_hz, 0.0, 1e4)

    @property
    def active(self) -> bool:
        """True when the fixed end moves."""
        return self.frequency_hz > 0 and (self.amplitude_x_m != 0 or self.amplitude_y_m != 0)


@dataclass(frozen=True, slots=True)
class RopeConfig:
    """The rope, its support and its environment.

    Parameters
    ----------
    length_m, diameter_m
        Unstretched length and diameter (a solid circular section unless `ei_nm2`/`ea_n` override it).
    youngs_modulus_pa, density_kg_m3
        Material. The paper's Kevlar rope: 1.24e11 Pa; density 1440 kg/m^3 (the paper gives none).
    ei_nm2, ea_n
        Bending and axial stiffness overrides; None derives them from E and the solid section. A braided rope
        bends far more easily than a solid rod of its diameter: give its measured (or fitted) EI here.
    fixed_end
        "pinned" (position fixed, slope free) or "clamped" (slope fixed along the initial direction too).
    angle_deg
        Direction of the initially straight rope, measured from +x towards +y (down); 0 is horizontal.
    initial_angular_velocity_rad_s
        Initial rigid rotation rate about the fixed end (positive turns +x towards +y).
    gravity_m_s2
        Gravitational acceleration along +y.
    drag_coefficient, air_density_kg_m3
        Aerodynamic drag on the velocity normal to the rope, per unit length ``0.5 rho_air Cd d |v_n| v_n``
        (the paper's rope: Cd = 1.122). 0 switches drag off.
    mass_damping_per_s
        Viscous (mass-proportional) damping coefficient alpha: force ``-alpha m v`` per unit length.
    material_damping_s
        Kelvin-Voigt material damping beta: stresses ``E (eps + beta d eps/dt)`` and likewise for bending.
    fixed_end_motion
        Optional prescribed motion of the fixed end.
    """

    length_m: float = 1.0
    diameter_m: float = 0.001
    youngs_modulus_pa: float = 1.24e11
    density_kg_m3: float = 1440.0
    ei_nm2: float | None = None
    ea_n: float | None = None
    fixed_end: Literal["pinned", "clamped"] = "pinned"
    angle_deg: float = 0.0
    initial_angular_velocity_rad_s: float = 0.0
    gravity_m_s2: float = 9.81
    drag_coefficient: float = 0.0
    air_density_kg_m3: float = 1.204
    mass_damping_per_s: float = 0.0
    material_damping_s: float = 0.0
    fixed_end_motion: FixedEndMotion = field(default_factory=FixedEndMotion)

    def __post_init__(self) -> None:
        check_positive("length_m", self.length_m)
        check_positive("diameter_m", self.diameter_m)
        check_positive("youngs_modulus_pa", self.youngs_modulus_pa)
        check_positive("density_kg_m3", self.density_kg_m3)
        if self.ei_nm2 is not None:
            check_positive("ei_nm2", self.ei_nm2)
        if self.ea_n is not None:
            check_positive("ea_n", self.ea_n)
        if self.fixed_end not in ("pinned", "clamped"):
            raise ValueError(f"fixed_end must be 'pinned' or 'clamped', got {self.fixed_end!r}")
        check_range("angle_deg", self.angle_deg, -360.0, 360.0)
        check_finite("initial_angular_velocity_rad_s", self.initial_angular_velocity_rad_s)
        check_range("gravity_m_s2", self.gravity_m_s2, -100.0, 100.0)
        check_range("drag_coefficient", self.drag_coefficient, 0.0, 100.0)
        check_range("air_density_kg_m3", self.air_density_kg_m3, 0.0, 100.0)
        check_range("mass_damping_per_s", self.mass_damping_per_s, 0.0, 1e6)
        check_range("material_damping_s", self.material_damping_s, 0.0, 10.0)

    @property
    def area_m2(self) -> float:
        """Cross-section area pi d^2 / 4."""
        return math.pi * self.diameter_m**2 / 4.0

    @property
    def axial_stiffness_n(self) -> float:
        """EA in N."""
        return self.ea_n if self.ea_n is not None else self.youngs_modulus_pa * self.area_m2

    @property
    def bending_stiffness_nm2(self) -> float:
        """EI in N m^2."""
        return self.ei_nm2 if self.ei_nm2 is not None else self.youngs_modulus_pa * math.pi * self.diameter_m**4 / 64

    @property
    def mass_per_length_kg_m(self) -> float:
        """rho A in kg/m."""
        return self.density_kg_m3 * self.area_m2

    @property
    def potential_scale_j(self) -> float:
        """m g L / 2: the potential energy released by a rigid rod falling from horizontal to vertical."""
        return self.mass_per_length_kg_m * self.length_m * abs(self.gravity_m_s2) * self.length_m / 2


@dataclass(frozen=True, slots=True)
class SolverConfig:
    """Discretisation and time integration.

    Parameters
    ----------
    elements
        Number of equal ANCF cable elements N.
    step_s
        Time step h of the generalized-alpha integrator.
    duration_s
        Simulated time.
    output_every_s
        Sample spacing of the stored trajectory (a multiple of `step_s` is used: rounded to whole steps).
    spectral_radius
        rho_inf of generalized-alpha in [0, 1]: 1 conserves energy (no numerical damping), lower values damp the
        highest (axial) modes. 0.9 is Exudyn's default and ours.
    newton_tolerance_m
        Newton stops when the largest position update is below this (absolute, metres).
    max_iterations
        Newton iterations per step before the step counts as failed.
    adaptive
        On a failed step, retry with smaller steps (down to step_s / 64) instead of stopping.
    """

    elements: int = 16
    step_s: float = 1e-3
    duration_s: float = 2.0
    output_every_s: float = 1e-3
    spectral_radius: float = 0.9
    newton_tolerance_m: float = 1e-11
    max_iterations: int = 25
    adaptive: bool = True

    def __post_init__(self) -> None:
        if isinstance(self.elements, bool) or not isinstance(self.elements, int) or not 1 <= self.elements <= 4096:
            raise ValueError(f"elements must be an integer in [1, 4096], got {self.elements!r}")
        check_positive("step_s", self.step_s)
        check_positive("duration_s", self.duration_s)
        if self.step_s > self.duration_s:
            raise ValueError(f"step_s ({self.step_s}) must not be longer than duration_s ({self.duration_s})")
        check_positive("output_every_s", self.output_every_s)
        check_range("spectral_radius", self.spectral_radius, 0.0, 1.0)
        check_positive("newton_tolerance_m", self.newton_tolerance_m)
        if isinstance(self.max_iterations, bool) or not 1 <= self.max_iterations <= 1000:
            raise ValueError(f"max_iterations must be in [1, 1000], got {self.max_iterations!r}")

    @property
    def steps_per_output(self) -> int:
        """Whole time steps between stored samples (at least 1)."""
        return max(1, round(self.output_every_s / self.step_s))

    @property
    def total_steps(self) -> int:
        """Number of time steps: `duration_s` rounded up to a whole number of output samples.

        The trajectory therefore always reaches `duration_s` (its last sample may lie up to one output spacing past
        it), and samples lie on a uniform grid.
        """
        every = self.steps_per_output
        return every * math.ceil(self.duration_s / (self.step_s * every) - 1e-9)
