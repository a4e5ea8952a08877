"""Asperity laws: one module per law, numba kernels over scalars (SPEC §5)."""
