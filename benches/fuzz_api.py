"""The long profile of the API fuzz harness (tests/api_fuzz.py): many generated calls, each run in
a worker process; prints the counts of every outcome and the first failures of each kind.

    python benches/fuzz_api.py --examples 2000            # per family
    python benches/fuzz_api.py --examples 200 --family batch --seed 3

Exit status 1 when any call aborted, panicked, hung, returned NaN/inf or raised a foreign error.
"""

from __future__ import annotations

import argparse
import sys
import time
from collections import Counter
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))

import api_fuzz  # noqa: E402
from hypothesis import HealthCheck, given, seed, settings  # noqa: E402


def run_family(harness: api_fuzz.Harness, name: str, examples: int, rng_seed: int) -> Counter[str]:
    before = Counter(harness.counts)

    @seed(rng_seed)
    @settings(max_examples=examples, deadline=None, database=None, suppress_health_check=list(HealthCheck), phases=("generate",))
    @given(api_fuzz.families()[name])
    def explore(node: object) -> None:
        harness.run(node)

    explore()
    return harness.counts - before


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--examples", type=int, default=1000, help="generated calls per family")
    ap.add_argument("--family", action="append", choices=sorted(api_fuzz.families()), help="only these families (repeatable)")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--show", type=int, default=3, help="failures shown per kind")
    ap.add_argument("--errors", type=int, default=0, help="show the N most common clean errors (what the calls reach)")
    args = ap.parse_args()
    harness = api_fuzz.Harness()
    start = time.monotonic()
    try:
        for name in args.family or sorted(api_fuzz.families()):
            c = run_family(harness, name, args.examples, args.seed)
            print(f"{name:12s} " + " ".join(f"{k}={c[k]}" for k in ("calls", "ok", "error", *api_fuzz.FAILURES)), flush=True)
    finally:
        harness.close()
    total = harness.counts
    print(f"{'total':12s} " + " ".join(f"{k}={total[k]}" for k in ("calls", "ok", "error", *api_fuzz.FAILURES)))
    print(f"{time.monotonic() - start:.0f} s")
    for message, n in harness.errors.most_common(args.errors):
        print(f"{n:6d}  {message}")
    for kind, examples in harness.examples.items():
        print(f"\n== {kind}: {len(examples)}")
        for e in examples[: args.show]:
            print(" ", e)
    return 1 if any(total[k] for k in api_fuzz.FAILURES) else 0


if __name__ == "__main__":
    sys.exit(main())
