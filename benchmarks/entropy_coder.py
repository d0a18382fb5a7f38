"""Why the entropy coder is written here: per-decision cost of adaptive binary coding.

Codes the same 1,000,000 context-modelled binary decisions (a skewed source, 64 adaptive
contexts) three ways and prints the time of each:

* this package's range coder, compiled with numba together with its adaptation
  (``bandelets.coding.rangecoder.code_flags``);
* ``constriction``'s range coder, called from Python once per decision with an adaptive
  Bernoulli model updated in Python (what context modelling that depends on just-decoded
  values forces on a library coder);
* ``constriction`` called once on the whole array with fixed, pre-computed probabilities (a
  lower bound for it: no adaptation, no context modelling).

    pip install constriction && python benchmarks/entropy_coder.py
"""

from __future__ import annotations

import time

import numpy as np

from bandelets.coding import rangecoder

N = 1_000_000
N_PY = 50_000  # the per-call loop is timed on a slice and scaled


def main() -> None:
    rng = np.random.default_rng(0)
    contexts = rng.integers(0, 64, N)
    bits = (rng.random(N) < 0.02 + 0.9 * (contexts / 64) ** 4).astype(np.int64)
    rangecoder.code_flags(rangecoder.Coder(64), bits[:1000], contexts[:1000])  # compile
    start = time.perf_counter()
    coder = rangecoder.Coder(64)
    rangecoder.code_flags(coder, bits, contexts)
    ours = time.perf_counter() - start
    size = len(coder.finish())
    print(f"bandelets.coding.rangecoder (numba)      {ours * 1e9 / N:8.1f} ns/decision  {size} bytes")
    try:
        import constriction
    except ImportError:
        print("constriction is not installed: pip install constriction")
        return
    encoder = constriction.stream.queue.RangeEncoder()
    p = np.full(64, 0.5)
    n = np.ones(64)
    start = time.perf_counter()
    for b, c in zip(bits[:N_PY], contexts[:N_PY], strict=True):
        encoder.encode(
            int(b), constriction.stream.model.Bernoulli(float(min(max(p[c], 1e-4), 1 - 1e-4)), perfect=False)
        )
        n[c] += 1
        p[c] += (b - p[c]) / n[c]
    per_call = time.perf_counter() - start
    print(f"constriction, per call         {per_call * 1e9 / N_PY:8.1f} ns/decision")
    probabilities = np.clip(bits.mean() + np.zeros(N), 1e-4, 1 - 1e-4)
    encoder = constriction.stream.queue.RangeEncoder()
    start = time.perf_counter()
    encoder.encode(bits.astype(np.int32), constriction.stream.model.Bernoulli(perfect=False), probabilities)
    batch = time.perf_counter() - start
    print(f"constriction, batch, no model  {batch * 1e9 / N:8.1f} ns/decision")


if __name__ == "__main__":
    main()
