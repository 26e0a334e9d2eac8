"""Pure numerical kernels (numba). Nothing here knows about graphs or YAML."""
