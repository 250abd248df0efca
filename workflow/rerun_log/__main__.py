"""``python -m workflow.rerun_log [model ...]``: the logging overhead per model."""
import sys

from .overhead import measure_overhead

if __name__ == "__main__":
    for name in sys.argv[1:] or ["arm2"]:
        r = measure_overhead(name)
        print(f"{name}: {r['frames']} frames; wall: bare {r['bare_us_per_frame']:.1f} us/frame, logged "
              f"{r['logged_us_per_frame']:.1f}, overhead {100 * r['overhead']:.1f} %; cpu: bare "
              f"{r['bare_us_per_frame_cpu']:.1f}, logged {r['logged_us_per_frame_cpu']:.1f}, overhead "
              f"{100 * r['overhead_cpu']:.1f} %; setup {r['setup_ms']:.1f} ms; {r['rrd_bytes'] / 1e6:.2f} MB")
