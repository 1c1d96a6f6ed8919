"""No false alarms for the external clients: N repeated runs of an unchanged tree all ``pass``.

``python tools/client_reruns.py [N] [CLIENT ...]`` runs every check of compare/budgets/clients.toml
(or those of the named clients, e.g. ``threejs sample-viewer``) N times (default 20), each run with a
fresh, empty ``$PBRCHECK_CACHE`` (a fresh scene export and a fresh headless Chromium per render),
against the committed baselines, and prints a line per run and a Markdown table per client (runs,
passes, the other outcomes, seconds per run). The test suite runs a reduced form for three.js
(tests/test_gate_plants.py, ``THREEJS_RERUNS``); the table of this script is in docs/compare.md.
"""

from __future__ import annotations

import statistics
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests"))
sys.path.insert(0, str(ROOT))

from compare.gate import load_budget  # noqa: E402
from gate_plants import CLIENTS, rerun_checks  # noqa: E402


def main(argv: list[str]) -> int:
    n = int(argv[0]) if argv and argv[0].isdigit() else 20
    wanted = [a for a in argv if not a.isdigit()]
    checks = load_budget(CLIENTS).checks
    clients = {}
    for c in checks:
        clients.setdefault(c.preset.removeprefix("ext:"), []).append(c.name)
    rows = ["| client | checks | runs | all pass | other outcomes | seconds per run (median, max) |",
            "|---|---|---|---|---|---|"]
    bad = 0
    for client in wanted or list(clients):
        if client not in clients:
            print(f"no checks of ext:{client} in {CLIENTS}", file=sys.stderr)
            return 2
        names = clients[client]
        print(f"{client}: {n} runs of {', '.join(names)}", flush=True)
        with tempfile.TemporaryDirectory(prefix="pbrcheck-reruns-") as d:
            runs = rerun_checks(CLIENTS, names, n, Path(d), stream=sys.stdout)
        other = [f"run {r['run'] + 1}: {k} {v}" + (f" ({r['errors'][k]})" if k in r["errors"] else "")
                 for r in runs for k, v in r["outcomes"].items() if v != "pass"]
        bad += bool(other)
        secs = [r["seconds"] for r in runs]
        rows.append(f"| {client} | {', '.join(names)} | {n} | {'yes' if not other else 'no'} | "
                    f"{'; '.join(other) or 'none'} | {statistics.median(secs):.1f}, {max(secs):.1f} |")
        print("\n".join(rows), flush=True)
    return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
