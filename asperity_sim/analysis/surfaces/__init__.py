"""Measured and synthetic surfaces: read topographies, find summits, fit the model, solve the exact contact.

:mod:`~asperity_sim.analysis.surfaces.topography` (surfaces and how they are read or made),
:mod:`~asperity_sim.analysis.surfaces.summits` (summits and spectral moments),
:mod:`~asperity_sim.analysis.surfaces.scale` (the cutoff filter, the height step, the automatic cutoff),
:mod:`~asperity_sim.analysis.surfaces.diagnosis` (at which scale a fit describes the surface, and its warnings),
:mod:`~asperity_sim.analysis.surfaces.fitting` (InterfaceParams and populations from summits) and
:mod:`~asperity_sim.analysis.surfaces.bem` (the boundary-element solution, tamaas),
:mod:`~asperity_sim.analysis.surfaces.pair` (what two surfaces tell beyond heights: e and the contact slopes).
For the comparison with exact contact mechanics (``scenarios/exact_contact.py``):
:mod:`~asperity_sim.analysis.surfaces.elliptic` (elliptic summits, the Hertz elliptic contact),
:mod:`~asperity_sim.analysis.surfaces.contact_scale` (summit curvatures at the scale of the contacts),
:mod:`~asperity_sim.analysis.surfaces.variants` (the model variants at given pressures),
:mod:`~asperity_sim.analysis.surfaces.tangential` (the frictional boundary-element solution) and
:mod:`~asperity_sim.analysis.surfaces.shear` (the ``mdr`` law at a pressure and shear tractions).
"""

from ...errors import SurfaceError, SurfaceScaleWarning
from .bem import bem_contact, plot_fit
from .diagnosis import ScaleReport
from .fitting import FitResult, empirical_population, fit, scene_text
from .scale import auto_cutoff, height_step, s_filter
from .summits import IDENTIFIED, NOT_IDENTIFIED, Summits, find_summits, nayak, spectral_moments
from .topography import INSTALL_HINT, Surface, composite, read, synthetic

__all__ = ["SurfaceError", "SurfaceScaleWarning", "Surface", "bem_contact", "Summits", "FitResult", "ScaleReport",
           "read", "composite", "synthetic", "find_summits", "fit", "empirical_population", "spectral_moments",
           "nayak", "scene_text", "plot_fit", "s_filter", "height_step", "auto_cutoff",
           "IDENTIFIED", "NOT_IDENTIFIED", "INSTALL_HINT"]
