"""pneumasim: pneumatics."""
