"""pneumasim: pneumatics."""
from .compile_cache import key_the_cache

# before any compiled function is decorated: numba's cache keyed by all compiled sources
key_the_cache()
