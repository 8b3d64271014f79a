"""Record the causal estimator's golden outputs (the regression test of issue 37's rewrite).

Run once on the release before a change (and again, in the same commit, where a change alters
results on purpose, saying why):

    .venv/bin/python test/golden/record.py [hostile] [broad]

Two sets:
* ``hostile.npz`` + ``hostile.json``: every mode of :data:`golden_cases.MODES` on the hostile
  rest–motion–rest recording, through ``push()`` sample by sample and through ``run()``:
  attitudes, per-axis orientation variances, and every count, note, bias and alignment figure;
* ``broad.npz`` + ``broad.json``: ``replay --estimator causal`` of each shared BROAD recording
  in every aiding mode: every 25th attitude and orientation variance of the output (the
  attitude is integrated, so a difference at any sample persists into the later ones), the
  last one, and the summary's counts and notes.
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))

from golden_cases import (  # noqa: E402
    AIDINGS,
    BROAD_STRIDE,
    MODES,
    broad_files,
    broad_outputs,
    hostile_outputs,
)


def main(which=("hostile", "broad")) -> None:
    if "hostile" in which:
        record_hostile()
    if "broad" in which:
        record_broad()


def record_hostile() -> None:
    arrays, meta = {}, {}
    for mode in sorted(MODES):
        for form in ("push", "run"):
            a, m = hostile_outputs(mode, form)
            for k, x in a.items():
                arrays[f"{mode}/{form}/{k}"] = x
            meta[f"{mode}/{form}"] = m
    np.savez_compressed(HERE / "hostile.npz", **arrays)
    (HERE / "hostile.json").write_text(json.dumps(meta, indent=1, sort_keys=True) + "\n")


def record_broad() -> None:
    arrays, meta = {}, {}
    for path in broad_files():
        for aiding in AIDINGS:
            a, m = broad_outputs(path, aiding)
            for k, x in a.items():
                arrays[f"{path.stem}/{aiding}/{k}"] = x
            meta[f"{path.stem}/{aiding}"] = m
            print(path.stem, aiding, m["attitude_messages"], flush=True)
    np.savez_compressed(HERE / "broad.npz", **arrays)
    (HERE / "broad.json").write_text(json.dumps(meta, indent=1, sort_keys=True) + "\n")
    print(f"stride {BROAD_STRIDE}")


if __name__ == "__main__":
    main(tuple(sys.argv[1:]) or ("hostile", "broad"))
