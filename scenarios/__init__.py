"""pneumasim: scenarios."""
