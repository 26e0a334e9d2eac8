"""Pure numerical kernels (numba). Nothing here knows about graphs or YAML."""

from ..cache import configure_numba_cache

configure_numba_cache()  # numba binds a kernel's cache folder when it is decorated: choose it first (flowtex.cache)
