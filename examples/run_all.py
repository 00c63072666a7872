"""Run every example and record its output and run time in docs/examples-output/
(the documentation site shows these files).

    .venv/bin/python examples/run_all.py [NAME ...]     # every example, or those named
"""

import subprocess
import sys
import tempfile
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
EXAMPLES = ("denoise_a_scan", "denoise_a_folder", "compress_vs_draco", "hash_under_attacks",
            "statistics_figure", "gradient_through_a_flow")


def main() -> int:
    dest = HERE.parent / "docs" / "examples-output"
    dest.mkdir(parents=True, exist_ok=True)
    failed = 0
    with tempfile.TemporaryDirectory() as tmp:
        names = sys.argv[1:] or EXAMPLES
        unknown = sorted(set(names) - set(EXAMPLES))
        if unknown:
            print(f"unknown example(s) {unknown}; choose from {EXAMPLES}", file=sys.stderr)
            return 2
        for name in names:
            start = time.perf_counter()
            run = subprocess.run([sys.executable, str(HERE / f"{name}.py"), "--out", tmp],
                                 capture_output=True, text=True, cwd=HERE)
            seconds = time.perf_counter() - start
            text = run.stdout.replace(tmp, "example-out")
            if run.returncode:
                failed += 1
                text += f"\n(failed, exit {run.returncode})\n{run.stderr[-2000:]}"
            (dest / f"{name}.txt").write_text(f"$ python examples/{name}.py\n{text}"
                                              f"# {seconds:.1f} s on this machine, including Python and JAX start-up\n")
            print(f"{name}: {'ok' if not run.returncode else 'FAILED'} in {seconds:.1f} s")
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
