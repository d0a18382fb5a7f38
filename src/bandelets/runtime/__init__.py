"""What every layer may use and that is no part of the codec: progress lines, the numba kernel cache, the
thread pool."""
