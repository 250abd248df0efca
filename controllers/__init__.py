"""pneumasim: controllers."""
