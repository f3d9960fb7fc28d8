#!/usr/bin/env python3
"""Reference values for tests/jr2/metrics_test.cpp, from scikit-learn and numpy.

Reads a JSON list of cases, each {"searches": [{"scores": [...], "mate": i}],
"fars": [...], "fpirs": [...], "max_rank": R, "cmc_ranks": K}, and writes, per
case: the ROC from sklearn.metrics.roc_curve(drop_intermediate=False), TAR at
each FAR read off that ROC, the CMC and FNIR at each FPIR written from their
definitions (docs/eval.md). Usage: metrics_reference.py IN.json OUT.json
"""
import json
import math
import sys

import numpy as np
from sklearn.metrics import roc_curve


def k_th(p, n):
    return max(1, math.floor(p * n + 1e-9 * p * n))


def case_reference(case):
    searches = case["searches"]
    genuine, impostor = [], []
    for s in searches:
        for i, v in enumerate(s["scores"]):
            (genuine if i == s["mate"] else impostor).append(v)
    y = np.r_[np.ones(len(genuine)), np.zeros(len(impostor))]
    fpr, tpr, thr = roc_curve(y, np.r_[genuine, impostor], drop_intermediate=False)
    out = {"roc_far": fpr.tolist(), "roc_tar": tpr.tolist(),
           "roc_threshold": [t if math.isfinite(t) else None for t in thr.tolist()]}
    # TAR at FAR from sklearn's ROC: the best TAR among thresholds whose FAR
    # is at most (k - 1)/N_imp (accepting s > t with t the k-th largest
    # impostor score is accepting s >= the next distinct score above t).
    n_imp = len(impostor)
    out["tar"] = []
    for far in case["fars"]:
        allowed = (k_th(far, n_imp) - 1) / n_imp
        out["tar"].append(float(np.max(tpr[fpr <= allowed + 1e-15])))
    # CMC from its definition.
    ranks = []
    for s in searches:
        if s["mate"] < 0:
            continue
        sc = np.asarray(s["scores"])
        mate = sc[s["mate"]]
        others = np.delete(sc, s["mate"])
        ranks.append(1 + int(np.sum(others >= mate)))
    ranks = np.asarray(ranks)
    out["cmc"] = [float(np.mean(ranks <= k)) for k in range(1, case["cmc_ranks"] + 1)]
    # FNIR at FPIR from the NIST FRVT definitions.
    nonmated_best = np.asarray([max(s["scores"]) for s in searches if s["mate"] < 0])
    mated = [s for s in searches if s["mate"] >= 0]
    out["fnir"] = []
    for p in case["fpirs"]:
        t = np.sort(nonmated_best)[::-1][k_th(p, len(nonmated_best)) - 1]
        misses = 0
        for s, r in zip(mated, ranks):
            if r > case["max_rank"] or not s["scores"][s["mate"]] > t:
                misses += 1
        out["fnir"].append(misses / len(mated))
    return out


def main():
    with open(sys.argv[1], encoding="utf-8") as f:
        cases = json.load(f)
    with open(sys.argv[2], "w", encoding="utf-8") as f:
        json.dump([case_reference(c) for c in cases], f)


if __name__ == "__main__":
    main()
