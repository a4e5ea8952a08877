"""Registry of output variables: name -> dims, dtype, units, long name.

The recorder builds datasets only from this table, so every variable written has CF
``units`` and a ``long_name`` (a test checks it).  A value with a Monte Carlo standard error
``<name>_stderr`` names it in its CF attribute ``ancillary_variables`` (:func:`standard_error_links`).
"""

from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class Var:
    dims: tuple
    dtype: str
    units: str
    long_name: str


STEP_VARIABLES = {
    "displacement": Var(("step", "axis"), "f8", "m",
                        "interface displacement Delta (axis 1: closure, axes 2-3: shear)"),
    "stress": Var(("step", "axis"), "f8", "Pa", "interface stress sigma (axis 1: compression positive)"),
    "stress_stderr": Var(("step", "axis"), "f8", "Pa",
                         "Monte Carlo standard error of the interface stress (0 where stress controlled)"),
    "displacement_stderr": Var(("step", "axis"), "f8", "m",
                               "Monte Carlo standard error of the solved displacement (0 where displacement controlled)"),
    "tangent": Var(("step", "axis", "axis_k"), "f8", "Pa m-1", "tangent stiffness d sigma_axis / d Delta_axis_k"),
    "n_contact": Var(("step",), "i8", "1", "number of sampled asperities in contact"),
    "n_slip": Var(("step",), "i8", "1", "number of sampled asperities in full slip"),
    "n_partial": Var(("step",), "i8", "1", "number of sampled asperities in partial slip (in contact, sheared, not in full slip)"),
    "theta_am": Var(("step",), "f8", "rad", "average asperity orientation extent theta_am (Eq. 29)"),
    "mean_theta": Var(("step",), "f8", "rad", "mean meridional orientation theta of the asperities in contact"),
    "contact_area_fraction": Var(("step",), "f8", "1",
                                 "real contact area per unit nominal area: the Hertz areas pi R delta_n of the "
                                 "contacts projected on the nominal plane (Monte Carlo estimate)"),
    "contact_area_fraction_stderr": Var(("step",), "f8", "1",
                                        "Monte Carlo standard error of the contact area fraction (under stress "
                                        "control with the error of the solved displacement propagated)"),
    "mean_gap": Var(("step",), "f8", "m",
                    "mean gap: distance from the flat to the mean plane of the rough surface, mean_plane_depth - "
                    "Delta_1 (the surface between contacts does not deform)"),
    "mean_gap_stderr": Var(("step",), "f8", "m",
                           "Monte Carlo standard error of the mean gap (that of Delta_1; 0 where displacement "
                           "controlled)"),
    "stage": Var(("step",), "i4", "1", "stage of the load path (0: initial state)"),
    "control": Var(("step", "axis"), "i1", "1", "control of each component (0: displacement, 1: stress)"),
    "iterations": Var(("step",), "i4", "1", "Newton iterations of the increment"),
    "residual": Var(("step",), "f8", "1", "final scaled residual max|sigma_f - target_f| / stress scale"),
    "cutbacks": Var(("step",), "i4", "1", "increment halvings before convergence"),
}

HISTORY_VARIABLES = {  # recorded for history laws only
    "external_work": Var(("step",), "f8", "J m-2",
                         "cumulative external work on the asperity contacts per unit nominal area"),
    "elastic_energy": Var(("step",), "f8", "J m-2",
                          "elastic energy stored in the contacts (Hertz and tangential springs) per unit nominal area"),
    "dissipation": Var(("step",), "f8", "J m-2", "cumulative frictional dissipation per unit nominal area"),
    "transitions": Var(("step", "from_state", "to_state"), "i8", "1",
                       "asperities changing contact state in the increment (0 out, 1 stick, 2 partial slip, 3 full slip)"),
}

LABEL_VARIABLES = {  # per-step labels (strings), written with the step variables
    "stage_name": Var(("step",), "U", "1",  # numpy str, as long as its longest value (so it reads back the same)
                      "name of the stage of the load path the step belongs to (step 0: initial state; "
                      "empty: an unnamed stage)"),
}

DOMAIN_VARIABLES = {  # recorded for path-independent laws only (asperity_sim.solve.domain)
    "law_domain": Var(("step",), "i1", "1",
                      "steps outside the law's domain (bits: 1 shear reversal or turn, 2 normal stress change during "
                      "shear, 4 negative external work over a closed loop; 0 inside)"),
}

ASPERITY_VARIABLES = {
    "r": Var(("asperity",), "f8", "m", "asperity height below the highest summit"),
    "R": Var(("asperity",), "f8", "m", "relative radius of curvature"),
    "u": Var(("asperity",), "f8", "rad", "shifted meridional coordinate u"),
    "phi": Var(("asperity",), "f8", "rad", "azimuth phi of the asperity contact"),
}

SNAPSHOT_VARIABLES = {
    "snapshot_step": Var(("snapshot",), "i8", "1", "step at which the snapshot was taken"),
    "asperity_delta_n": Var(("snapshot", "asperity"), "f8", "m", "normal overlap delta_n of each asperity"),
    "asperity_theta": Var(("snapshot", "asperity"), "f8", "rad", "meridional orientation theta of each asperity"),
    "asperity_force": Var(("snapshot", "asperity", "axis"), "f8", "N", "asperity contact force in the global frame"),
    "asperity_state": Var(("snapshot", "asperity"), "i1", "1",
                          "contact state (0: out of contact, 1: stick, 2: partial slip, 3: full slip)"),
}

COORDS = {
    "from_state": Var(("from_state",), "i4", "1", "contact state before the increment (0 out, 1 stick, 2 partial, 3 full slip)"),
    "to_state": Var(("to_state",), "i4", "1", "contact state after the increment (0 out, 1 stick, 2 partial, 3 full slip)"),
    "axis": Var(("axis",), "i4", "1", "component: 1 normal (closure), 2 and 3 shear"),
    "axis_k": Var(("axis_k",), "i4", "1", "displacement component of the tangent"),
}

ALL_VARIABLES = {**STEP_VARIABLES, **LABEL_VARIABLES, **HISTORY_VARIABLES, **DOMAIN_VARIABLES, **ASPERITY_VARIABLES, **SNAPSHOT_VARIABLES, **COORDS}

PROPERTY_VARIABLES = {  # derived joint properties (asperity_sim.analysis.properties, asperity_sim.runs.envelope); dims:
    # "point" stands for the grid and replica dimensions of the sweep they come from
    "peak_shear_stress": Var(("point",), "f8", "Pa", "peak shear stress: largest shear stress of the shear stage"),
    "peak_shear_displacement": Var(("point",), "f8", "m", "shear displacement at the peak shear stress"),
    "peak_normal_stress": Var(("point",), "f8", "Pa", "normal stress sigma_1 at the peak shear stress"),
    "peak_friction": Var(("point",), "f8", "1", "friction coefficient tau/sigma_1 at the peak shear stress"),
    "residual_shear_stress": Var(("point",), "f8", "Pa",
                                 "residual shear stress: shear stress at the last step of the shear stage"),
    "residual_friction": Var(("point",), "f8", "1", "friction coefficient tau/sigma_1 at the last step of shear"),
    "dilation_angle_peak": Var(("point",), "f8", "rad",
                               "dilation angle atan(-dDelta_1/ds) at the peak shear stress (positive: opening)"),
    "normal_stress_start": Var(("point",), "f8", "Pa", "normal stress sigma_1 at the start of shear"),
    "normal_stiffness": Var(("point",), "f8", "Pa m-1", "normal stiffness dsigma_1/dDelta_1 at the start of shear"),
    "shear_stiffness": Var(("point",), "f8", "Pa m-1",
                           "shear stiffness dtau/ds (tangent along the shear direction) at the start of shear"),
    "cycle_amplitude": Var(("point",), "f8", "m", "shear displacement amplitude a of the cycle (half its span)"),
    "secant_shear_stiffness": Var(("point",), "f8", "Pa m-1",
                                  "secant shear stiffness (tau(+a) - tau(-a)) / 2a of the cycle"),
    "secant_stiffness_ratio": Var(("point",), "f8", "1",
                                  "secant shear stiffness over the shear stiffness at the start of shear (G/Gmax)"),
    "loop_dissipation": Var(("point",), "f8", "J m-2",
                            "energy dissipated in the cycle: loop area, closed integral of tau ds (trapezoid)"),
    "cycle_dissipation": Var(("point",), "f8", "J m-2",
                             "increase of the recorded frictional dissipation over the cycle (history laws)"),
    "damping_ratio": Var(("point",), "f8", "1", "equivalent damping ratio W_d / (4 pi W_s), W_s = k_sec a2 / 2"),
    "secant_shear_stiffness_by_cycle": Var(("point", "cycle"), "f8", "Pa m-1", "secant shear stiffness of each cycle"),
    "loop_dissipation_by_cycle": Var(("point", "cycle"), "f8", "J m-2", "loop area of each cycle"),
    "cycle_dissipation_by_cycle": Var(("point", "cycle"), "f8", "J m-2",
                                      "increase of the recorded dissipation over each cycle (history laws)"),
    "damping_ratio_by_cycle": Var(("point", "cycle"), "f8", "1", "equivalent damping ratio of each cycle"),
    "mc_cohesion": Var(("strength",), "f8", "Pa", "Mohr-Coulomb cohesion c of tau = c + sigma_n tan(phi)"),
    "mc_friction_angle": Var(("strength",), "f8", "rad", "Mohr-Coulomb friction angle phi of tau = c + sigma_n tan(phi)"),
    "power_law_A": Var(("strength",), "f8", "Pa",
                       "power-law envelope coefficient A of tau = A (sigma_n / sigma_ref)^B (tau at sigma_ref)"),
    "power_law_B": Var(("strength",), "f8", "1", "power-law envelope exponent B of tau = A (sigma_n / sigma_ref)^B"),
}

ALL_VARIABLES = {**ALL_VARIABLES, **PROPERTY_VARIABLES}


INITIAL_STAGE_NAME = "initial state"  # stage_name of step 0


def run_variables(law) -> dict:
    """The per-step variables of a run of ``law`` (a :class:`~asperity_sim.laws.Law`), in their order.

    Every run: :data:`STEP_VARIABLES`; a history law: :data:`HISTORY_VARIABLES` and the law's own
    (``law.variables``: its event count); a path-independent law: :data:`DOMAIN_VARIABLES`.
    """
    if law.history is not None:
        return {**STEP_VARIABLES, **HISTORY_VARIABLES, **law.variables}
    return {**STEP_VARIABLES, **law.variables, **DOMAIN_VARIABLES}


def standard_error_links(names) -> dict:
    """{value: its standard error} for the variable names given: ``x`` -> ``x_stderr`` (runs) and
    ``x_mean`` -> ``x_sem`` (replica means of sweeps), where both are present; CF links them with
    the attribute ``ancillary_variables`` of the value."""
    names = set(names)
    links = {}
    for name in names:
        if name.endswith("_stderr") and name[: -len("_stderr")] in names:
            links[name[: -len("_stderr")]] = name
        elif name.endswith("_sem") and name[: -len("_sem")] + "_mean" in names:
            links[name[: -len("_sem")] + "_mean"] = name
    return links
