"""Several bracing-pair runs at once, round after round: every bag complete, every run's numbers
equal to a run done alone.

    source env.sh && python tools/stress_pairs.py [--runs 3] [--rounds 10] [--duration 10]
                                                 [--output out/stress]

First one run alone (the reference), then ``--rounds`` rounds of ``--runs`` runs started
together (braced voltage, free, braced torque, ... in turn). Prints per round each run's exit
code, the messages per topic in its bag against the steps, and whether its summary equals the
reference of its variant (every number but the wall-clock ones); exit 1 if anything differs.
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

from bracing_recorder.recorder import topic_table

# Variants taken in turn by the runs of a round (a user running braced, free and torque side by side).
VARIANTS: list[tuple[str, list[str]]] = [
    ("braced", []),
    ("free", ["--no-bracing"]),
    ("torque", ["--mode", "torque"]),
]
WALL_CLOCK_KEYS = {"wall_time_s", "real_time_factor"}


def pair(config: Path, output: Path, duration: float, extra: list[str]) -> subprocess.Popen[str]:
    argv = [sys.executable, "-m", "bracing_bringup.pair", "--config", str(config), "--output", str(output)]
    argv += ["--duration", str(duration), "--quiet", *extra]
    return subprocess.Popen(argv, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)


def bag_counts(bag: Path) -> dict[str, int]:
    from rosbags.rosbag2 import Reader

    counts: dict[str, int] = {}
    with Reader(bag) as reader:
        for connection in reader.connections:
            counts[connection.topic] = counts.get(connection.topic, 0) + connection.msgcount
    return counts


def physics(summary: dict[str, Any]) -> dict[str, Any]:
    return {k: v for k, v in summary.items() if k not in WALL_CLOCK_KEYS}


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0] if __doc__ else None)
    parser.add_argument("--config", type=Path, default=Path("config/paper_4link.yaml"))
    parser.add_argument("--runs", type=int, default=3, help="runs started together per round")
    parser.add_argument("--rounds", type=int, default=10)
    parser.add_argument("--duration", type=float, default=10.0, help="sim time per run [s]")
    parser.add_argument("--output", type=Path, default=Path("out/stress"))
    args = parser.parse_args(argv)
    steps = round(args.duration / 0.001) + 1
    failures = 0
    references: dict[str, dict[str, Any]] = {}
    for name, extra in VARIANTS[: args.runs]:
        out = args.output / "alone" / name
        if (out / "summary.json").exists():
            references[name] = json.loads((out / "summary.json").read_text())
            continue
        done = pair(args.config, out, args.duration, extra)
        text = done.communicate()[0]
        if done.returncode != 0:
            print(f"reference run {name} failed ({done.returncode}):\n{text}")
            return 1
        references[name] = json.loads((out / "summary.json").read_text())
    print(f"{args.rounds} rounds of {args.runs} bracing-pair runs at once, {args.duration:g} s each ({steps} states)")
    for round_no in range(1, args.rounds + 1):
        start = time.monotonic()
        procs = []
        for k in range(args.runs):
            name, extra = VARIANTS[k % len(VARIANTS)]
            out = args.output / f"round{round_no:02d}" / f"{k}-{name}"
            procs.append((name, out, pair(args.config, out, args.duration, extra)))
        lines = []
        for name, out, proc in procs:
            text = proc.communicate()[0]
            counts = bag_counts(out / "bag") if (out / "bag" / "metadata.yaml").exists() else {}
            contacts = [t.rsplit("/", 1)[1] for t in counts if t.startswith("/contact_wrench/")]
            per_step = {t for t, _, _ in topic_table(contacts)}  # one message per state each
            counts = {t: n for t, n in counts.items() if t in per_step or t.lstrip("/") in per_step}
            short = {topic: n for topic, n in counts.items() if n < steps}
            summary_file = out / "summary.json"
            same = summary_file.exists() and physics(json.loads(summary_file.read_text())) == physics(references[name])
            ok = proc.returncode == 0 and counts and not short and same
            failures += 0 if ok else 1
            fewest = min(counts.values()) if counts else 0
            lines.append(
                f"  {name:7s} exit {proc.returncode}  topics {len(counts)}  messages per topic >= {fewest} of {steps}"
                f"  summary {'= alone' if same else 'DIFFERS'}" + ("" if ok else f"  FAILED\n{text[-2000:]}")
            )
        print(f"round {round_no:2d} ({time.monotonic() - start:5.1f} s wall)")
        print("\n".join(lines), flush=True)
    total = args.rounds * args.runs
    print(f"{total - failures} of {total} runs complete and equal to a run done alone")
    return 1 if failures else 0


if __name__ == "__main__":
    sys.exit(main())
