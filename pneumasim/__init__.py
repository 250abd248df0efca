"""pneumasim: command line and benchmarks."""
