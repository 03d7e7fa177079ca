"""How long ``gpcd diagnose`` takes on the README's real UR10e example (issue 48).

Acceptance: "``gpcd diagnose`` on the README's example finishes in under 2
minutes on a 2-core machine". The example is one loaded identification run
of the UR10e logs (``ur10e_mamedov/identification_data/
ur-20_02_19_14harm50secLoad.csv``, 55.8 s, 5307 samples), diagnosed against
the built-in ``ur10e`` model with a plan asked for::

    gpcd diagnose --robot ur10e FILE --plan plan.csv

The command runs in process (:func:`sklearn_gpcd.cli.main`, this checkout's
package). Printed: wall-clock and CPU seconds (user + system of this
process, every thread), their ratio, the load average of the machine before
and after (other jobs share it: the wall-clock time on a busy machine is
longer than on an idle one, the CPU time is not) and the effects named.

Run::

    python benchmarks/diagnose_speed.py [--data DIR] [--repeat N]

Without the data it says so and exits 0.
"""

import argparse
import contextlib
import io
import os
import resource
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
sys.path.insert(0, str(Path(__file__).resolve().parent.parent))  # this checkout's package
from _common import real_data_path  # noqa: E402

from sklearn_gpcd.cli import main as gpcd  # noqa: E402

EXAMPLE = "ur10e_mamedov/identification_data/ur-20_02_19_14harm50secLoad.csv"


def _cpu():
    usage = resource.getrusage(resource.RUSAGE_SELF)
    return usage.ru_utime + usage.ru_stime


def run_once(path):
    """Wall and CPU seconds of one ``gpcd diagnose`` and the lines it printed."""
    with tempfile.TemporaryDirectory() as tmp:
        out = io.StringIO()
        load = os.getloadavg()
        wall, cpu = time.perf_counter(), _cpu()
        with contextlib.redirect_stdout(out), contextlib.redirect_stderr(io.StringIO()):
            code = gpcd(["diagnose", "--robot", "ur10e", str(path),
                         "--plan", str(Path(tmp) / "plan.csv")])
        wall, cpu = time.perf_counter() - wall, _cpu() - cpu
    return {"exit": code, "wall": wall, "cpu": cpu, "load_before": load,
            "load_after": os.getloadavg(), "text": out.getvalue()}


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--data", default=None, help="real-data root (default: the shared one)")
    parser.add_argument("--repeat", type=int, default=1)
    args = parser.parse_args(argv)
    root = real_data_path(".", args.data)
    path = None if root is None else Path(root) / EXAMPLE
    if path is None or not path.exists():
        print(f"the README example {EXAMPLE} is not here: skipped")
        return 0
    print(f"gpcd diagnose --robot ur10e {EXAMPLE} --plan plan.csv; {os.cpu_count()} cores")
    for k in range(args.repeat):
        r = run_once(path)
        named = [line.strip() for line in r["text"].splitlines()
                 if line.strip()[:3] in {f"{i}. " for i in range(1, 10)} and " on " in line]
        print(f"run {k + 1}: exit {r['exit']}, wall {r['wall']:.1f} s, CPU {r['cpu']:.1f} s "
              f"(CPU/wall {r['cpu'] / r['wall']:.2f}); load average "
              f"{r['load_before'][0]:.2f} before, {r['load_after'][0]:.2f} after "
              f"({os.cpu_count()} cores)")
        print("   " + "\n   ".join(n[:90] for n in named))
    return 0


if __name__ == "__main__":
    sys.exit(main())
