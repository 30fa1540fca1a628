#!/usr/bin/env python3
"""How few samples a period the identifier holds: the eveh harvester (`lssi gen eveh`, 1 %
noise, x only, mono- and bistable) sampled at 20–300 samples a forcing period, several seeds
each, identified as a user would (`lssi identify FILE --family odd --json`, and with
`--no-refine`: the streaming model a device computes), scored against the truth written beside
each recording. Prints a markdown table: per rate and well shape, the median (min–max) mean
coefficient error of the streaming and the printed model, spurious terms, withheld records,
and the rate `lssi identify` proposes for a device (`device_rate_hz`).

    .venv/bin/python bench/choice/rates.py --lssi target/release/lssi --seeds 6-10

Seeds 1–5 were used to choose the weak form's low-rate set-up (lssi-core's tuning); report
others.
"""

from __future__ import annotations

import argparse
import json
import math
import statistics
import subprocess
import sys
import tempfile
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
import testset  # noqa: E402  (score: the test set's scoring)

OMEGA = 21.4  # the eveh forcing, rad/s


def identify(lssi: str, csv: Path, refine: bool):
    args = [lssi, "identify", str(csv), "--family", "odd", "--json"]
    if not refine:
        args.append("--no-refine")
    p = subprocess.run(args, capture_output=True, text=True)
    if p.returncode == 3:
        return None, "withheld"
    if p.returncode != 0:
        return None, "failed"
    return json.loads(p.stdout), "ok"


def spread(values):
    if not values:
        return "–"
    return f"{statistics.median(values):.3g} ({min(values):.3g}–{max(values):.3g})"


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--lssi", default="target/release/lssi")
    ap.add_argument("--seeds", default="6-10", help="a range a-b of seeds")
    ap.add_argument("--rates", default="20,24,30,45,60,100,150,300",
                    help="samples a forcing period")
    args = ap.parse_args()
    a, b = (int(s) for s in args.seeds.split("-"))
    seeds = range(a, b + 1)
    print("| samples a period | wells | streaming err % | printed err % | spurious s/p "
          "| withheld | proposed device rate Hz |")
    print("|---:|---|---|---|---|---:|---|")
    with tempfile.TemporaryDirectory() as tmp:
        for per_period in (float(r) for r in args.rates.split(",")):
            rate = round(per_period * OMEGA / (2 * math.pi), 1)
            for wells in ["bistable", "monostable"]:
                stream_err, printed_err, sp_s, sp_p, withheld, proposed = [], [], 0, 0, 0, []
                for seed in seeds:
                    csv = Path(tmp) / f"p{per_period:g}-{wells}-{seed}.csv"
                    subprocess.run([args.lssi, "gen", "eveh", "--wells", wells, "--rate",
                                    str(rate), "--delta", "0.01",
                                    "--seed", str(seed * 1000 + int(per_period)), str(csv)],
                                   check=True, capture_output=True)
                    truth = json.loads(csv.with_suffix(".json").read_text())["terms"]
                    for refine in (False, True):
                        out, status = identify(args.lssi, csv, refine)
                        if out is None:
                            withheld += refine  # counted once, on the default run
                            continue
                        s = testset.score(out["terms"], truth)
                        if refine:
                            printed_err.append(s["error"])
                            sp_p += s["spurious"]
                            if out.get("device_rate_hz"):
                                proposed.append(out["device_rate_hz"])
                        else:
                            stream_err.append(s["error"])
                            sp_s += s["spurious"]
                prop = f"{min(proposed):g}–{max(proposed):g}" if proposed else "–"
                print(f"| {per_period:g} | {wells} | {spread(stream_err)} | "
                      f"{spread(printed_err)} | {sp_s}/{sp_p} | {withheld} | {prop} |",
                      flush=True)


if __name__ == "__main__":
    main()
