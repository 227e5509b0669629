"""Scan the outcome of a deflation's step across a volume bracket (docs/analysis.md, "Located
events"): for each target dV/V, (1) the protocol's step from the stored step before it, and
(2) the old branch continued to that volume without the jiggle, then jiggled and minimized there
with no change of volume. Prints one character per volume: ``o`` the old branch (a sphere),
``E`` buckled.

    python examples/threshold_scan.py RUN_FOLDER STEP FROM TO COUNT
    python examples/threshold_scan.py runs/g2333 4 0.058 0.076 19

``STEP`` is the stored step whose volume the shell first reached buckled (its events:
``shellbuckle analyze RUN_FOLDER``); the scan is two protocol steps per volume.
"""

import argparse

import numpy as np

from shellbuckle.locate import StepFromStored


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("run")
    parser.add_argument("step", type=int)
    parser.add_argument("start", type=float)
    parser.add_argument("stop", type=float)
    parser.add_argument("count", type=int)
    args = parser.parse_args()
    step_to = StepFromStored(args.run, args.step, threads=1)

    def outcome(shape):
        return "o" if shape == "sphere" else "E"

    volumes = np.linspace(args.start, args.stop, args.count)
    from_stored, at_volume = "", ""
    for v in volumes:
        from_stored += outcome(step_to.shape(v))
        quiet, quiet_record = step_to(v, jiggle=False)
        at_volume += outcome(step_to.shape(v, start=(quiet.X, quiet_record)))
    print("dV/V:", " ".join(f"{v:.4f}" for v in volumes))
    print("the step from the stored step:   ", from_stored)
    print("the branch jiggled at the volume:", at_volume)


if __name__ == "__main__":
    main()
