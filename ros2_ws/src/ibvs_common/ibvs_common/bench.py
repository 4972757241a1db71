"""The one line each package's ``python -m <package>.bench`` prints per timing (no rclpy)."""

from collections.abc import Sequence

import numpy as np


def print_timing(name: str, seconds: Sequence[float]) -> None:
    """Print the median and p95 (ms) and the count of per-iteration wall times ``seconds``."""
    s = np.asarray(seconds, dtype=float) * 1e3
    print(f'{name:62s} median {np.median(s):9.3f} ms   p95 {np.percentile(s, 95):9.3f} ms'
          f'   (n={s.size})', flush=True)
