"""pneumasim: pneumasim."""
