"""pneumasim: identification."""
