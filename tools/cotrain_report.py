#!/usr/bin/python3
"""Tables and the λ plot of the co-optimization study (docs/jr2.md §5).

Reads the `vkjr2 eval` results.json of the study's models and the JSON-lines
logs of their `vkjr2 cotrain` runs (RUN_DIR/NAME.jsonl), and writes a
markdown report: the co-training table (Pretrained, Fine-tune,
Restore-first, Align-first), the λ table, the trainable-layers table and the
unpaired row, each metric with its 95 % interval, per strength; the
held-out (training-split) scores the runs logged; and an SVG plot of PSNR
and TAR against λ.

    /usr/bin/python3 tools/cotrain_report.py RUN_DIR --eval RUN_DIR/eval/results.json \
        --out RUN_DIR/report.md --plot RUN_DIR/lambda.svg

Only the standard library is used. Missing runs are left out of their table.
"""

import argparse
import json
import math
import os
import sys
import tempfile

PRETRAINED = "restored:restorer_default"
MAIN = [("Degraded", "degraded"), ("Pretrained", PRETRAINED), ("Fine-tune (λ = 0)", "finetune"),
        ("Co-optimize, restore-first", "restore_first"),
        ("Co-optimize, align-first", "align_first")]
LAYERS = [("early", "layers_early"), ("middle", "layers_middle"), ("late", "layers_late"),
          ("all", "restore_first")]


class CliError(Exception):
    """A user-facing error: what went wrong and how to fix it."""


def load_json(path, what):
    try:
        with open(path, encoding="utf-8") as f:
            return json.load(f)
    except OSError as e:
        raise CliError(f"cannot read {what} {path}: {e.strerror}; run the study first") from e
    except json.JSONDecodeError as e:
        raise CliError(f"{what} {path} is not JSON ({e})") from e


def method_name(run):
    return run if run.startswith("restored") or run == "degraded" else "restored:" + run


def pct(x):
    return "—" if x is None or not math.isfinite(x) else f"{100 * x:.1f}"


def interval(entry, scale=100.0, digits=1):
    if entry is None or entry.get("value") is None:
        return "—"
    v = entry["value"]
    lo, hi = entry.get("ci95", [None, None])
    f = f"{{:.{digits}f}}"
    if lo is None or hi is None:
        return f.format(scale * v)
    return f"{f.format(scale * v)} [{f.format(scale * lo)}, {f.format(scale * hi)}]"


def pick(row, key, field, target):
    for e in row.get(key, []):
        if abs(e.get(field, -1) - target) < 1e-12 and e.get("reported", True):
            return e
    return None


COLUMNS = ["TAR@FAR 10⁻¹ (%)", "TAR@FAR 10⁻² (%)", "Rank-1 (%)", "Rank-5 (%)",
           "FNIR@FPIR 10⁻¹ (%)", "PSNR (dB)", "SSIM"]


def cells(row):
    rank = {e["rank"]: e for e in row.get("rank", [])}
    return [interval(pick(row, "tar_at_far", "far", 1e-1)),
            interval(pick(row, "tar_at_far", "far", 1e-2)),
            interval(rank.get(1)), interval(rank.get(5)),
            interval(pick(row, "fnir_at_fpir", "fpir", 1e-1)),
            interval(row.get("psnr_db"), 1.0, 2), interval(row.get("ssim"), 1.0, 3)]


def table(title, labelled, rows_by_method, strengths):
    """labelled: [(label, method)] → markdown rows per strength."""
    out = [f"### {title}", "",
           "| strength | configuration | " + " | ".join(COLUMNS) + " |",
           "|---|---|" + "---|" * len(COLUMNS)]
    any_row = False
    for s in strengths:
        for label, method in labelled:
            row = rows_by_method.get((method, s))
            if row is None:
                continue
            any_row = True
            out.append(f"| {s} | {label} | " + " | ".join(cells(row)) + " |")
    return out + [""] if any_row else []


def last_heldout(run_dir, run):
    path = os.path.join(run_dir, run + ".jsonl")
    if not os.path.exists(path):
        return None
    last = None
    with open(path, encoding="utf-8") as f:
        for line in f:
            j = json.loads(line)
            if "student" in j:
                last = j
    return last


def svg_plot(path, lambdas, series_psnr, series_tar):
    """Two panels: PSNR and TAR@FAR 10⁻¹ against log10 λ, one line per strength."""
    w, h, pad = 900, 380, 60
    colours = ["#1f77b4", "#ff7f0e", "#2ca02c", "#d62728"]
    xs = [math.log10(x) for x in lambdas]
    x0, x1 = min(xs) - 0.2, max(xs) + 0.2

    def panel(ox, title, series, unit):
        ys = [y for _, pts in series for _, y in pts if y is not None]
        if not ys:
            return []
        y0, y1 = min(ys), max(ys)
        if y1 - y0 < 1e-9:
            y0, y1 = y0 - 1, y1 + 1
        m = 0.1 * (y1 - y0)
        y0, y1 = y0 - m, y1 + m
        pw, ph = w / 2 - pad - 20, h - 2 * pad

        def X(x):
            return ox + pad + (math.log10(x) - x0) / (x1 - x0) * pw

        def Y(y):
            return pad + (1 - (y - y0) / (y1 - y0)) * ph

        g = [f'<rect x="{ox + pad}" y="{pad}" width="{pw}" height="{ph}" fill="none" stroke="#444"/>',
             f'<text x="{ox + pad + pw / 2}" y="{pad - 20}" text-anchor="middle" '
             f'font-size="15">{title}</text>',
             f'<text x="{ox + pad + pw / 2}" y="{h - 15}" text-anchor="middle" '
             f'font-size="13">λ (log scale)</text>',
             f'<text x="{ox + 15}" y="{pad + ph / 2}" font-size="13" '
             f'transform="rotate(-90 {ox + 15} {pad + ph / 2})" text-anchor="middle">{unit}</text>']
        for lam in lambdas:
            g.append(f'<text x="{X(lam):.1f}" y="{pad + ph + 18}" text-anchor="middle" '
                     f'font-size="11">{lam:g}</text>')
        for k in range(5):
            yv = y0 + (y1 - y0) * k / 4
            g.append(f'<text x="{ox + pad - 6}" y="{Y(yv) + 4:.1f}" text-anchor="end" '
                     f'font-size="11">{yv:.3g}</text>')
        for i, (label, pts) in enumerate(series):
            pts = [(x, y) for x, y in pts if y is not None]
            if not pts:
                continue
            c = colours[i % len(colours)]
            d = " ".join(f"{X(x):.1f},{Y(y):.1f}" for x, y in pts)
            g.append(f'<polyline points="{d}" fill="none" stroke="{c}" stroke-width="2"/>')
            for x, y in pts:
                g.append(f'<circle cx="{X(x):.1f}" cy="{Y(y):.1f}" r="3.5" fill="{c}"/>')
            g.append(f'<text x="{ox + pad + pw - 8}" y="{pad + 18 + 16 * i}" text-anchor="end" '
                     f'font-size="12" fill="{c}">{label}</text>')
        return g

    body = panel(0, "Image quality", series_psnr, "PSNR (dB)") + \
        panel(w / 2, "Recognition", series_tar, "TAR@FAR 10⁻¹ (%)")
    text = (f'<svg xmlns="http://www.w3.org/2000/svg" width="{w}" height="{h}" '
            f'font-family="sans-serif"><rect width="{w}" height="{h}" fill="white"/>'
            + "".join(body) + "</svg>\n")
    write_atomic(path, text)


def write_atomic(path, text):
    d = os.path.dirname(os.path.abspath(path))
    fd, tmp = tempfile.mkstemp(dir=d, prefix=".tmp-")
    with os.fdopen(fd, "w", encoding="utf-8") as f:
        f.write(text)
    os.chmod(tmp, 0o644)
    os.replace(tmp, path)


def main(argv):
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("run_dir")
    p.add_argument("--eval", required=True, action="append",
                   help="results.json of vkjr2 eval (repeatable: the rows are merged)")
    p.add_argument("--out", required=True, help="the markdown report")
    p.add_argument("--plot", help="the λ plot (SVG)")
    p.add_argument("--lambda-main", type=float, default=10, help="λ of restore_first")
    a = p.parse_args(argv)
    rows = {}
    strengths = []
    evals = [load_json(path, "evaluation") for path in a.eval]
    for path, ev in zip(a.eval, evals):
        if ev.get("split") != evals[0].get("split"):
            raise CliError(f"{path} is of split {ev.get('split')}, {a.eval[0]} of "
                           f"{evals[0].get('split')}; merge evaluations of one split")
        for r in ev.get("rows", []):
            rows[(r["method"], r["strength"])] = r
            if r["strength"] not in strengths:
                strengths.append(r["strength"])
    if not rows:
        raise CliError(f"{', '.join(a.eval)} hold no rows")
    ev = evals[0]
    out = ["# Co-optimization study", "",
           f"Split {ev['split']} of the benchmark, alignment {ev['rows'][0]['align']}, "
           f"{ev['bootstrap']['resamples']} bootstrap resamples "
           f"({ev['bootstrap']['unit']}); values with 95 % intervals.", ""]

    def lab(pairs):
        return [(label, method_name(run)) for label, run in pairs]

    out += table("Co-training", lab(MAIN), rows, strengths)
    lambdas = sorted([(0.0, "finetune"), (a.lambda_main, "restore_first"), (30.0, "lambda_30"),
                      (100.0, "lambda_100"), (300.0, "lambda_300"), (1000.0, "lambda_1000")])
    out += table("λ sweep", [(f"λ = {lam:g}", method_name(run)) for lam, run in lambdas],
                 rows, strengths)
    def ran(*runs):  # a table only when one of its own runs was evaluated
        return any((method_name(r), st) in rows for r in runs for st in strengths)

    if ran("layers_early", "layers_middle", "layers_late"):
        out += table("Trainable layers", [(f"{g}", method_name(run)) for g, run in LAYERS],
                     rows, strengths)
    if ran("unpaired"):
        out += table("Unpaired data", lab([("Pretrained", PRETRAINED),
                                            ("Co-optimize, paired", "restore_first"),
                                            ("Co-optimize, unpaired", "unpaired")]),
                     rows, strengths)
    # What the runs logged on their held-out clips (training split: the
    # numbers λ and the layers are chosen by).
    held = ["### Held-out clips of the training split (the runs' last scores)", "",
            "| run | steps | rank-1 student / teacher / degraded (%) | genuine cosine "
            "student / teacher | PSNR student / teacher / degraded (dB) |", "|---|---|---|---|---|"]
    runs = ["finetune", "restore_first", "align_first", "lambda_30", "lambda_100", "lambda_300",
            "lambda_1000", "layers_early", "layers_middle", "layers_late", "unpaired"]
    n_held = 0
    for run in runs:
        j = last_heldout(a.run_dir, run)
        if j is None:
            continue
        n_held += 1
        s, t, d = j["student"], j["teacher"], j["degraded"]

        def db(x):
            return f"{x['psnr']:.2f}" if "psnr" in x else "—"
        held.append(f"| {run} | {j['step']} | {pct(s['top1'])} / {pct(t['top1'])} / "
                    f"{pct(d['top1'])} | {s['genuine_cos']:.4f} / {t['genuine_cos']:.4f} | "
                    f"{db(s)} / {db(t)} / {db(d)} |")
    if n_held:
        out += held + [""]
    write_atomic(a.out, "\n".join(out) + "\n")
    if a.plot:
        present = [(lam, run) for lam, run in lambdas if lam > 0 and
                   any((method_name(run), s) in rows for s in strengths)]
        if len(present) >= 2:
            ps, ts = [], []
            for s in strengths:
                pts_p, pts_t = [], []
                for lam, run in present:
                    r = rows.get((method_name(run), s))
                    pts_p.append((lam, r["psnr_db"]["value"] if r else None))
                    t = pick(r, "tar_at_far", "far", 1e-1) if r else None
                    pts_t.append((lam, 100 * t["value"] if t and t["value"] is not None else None))
                ps.append((s, pts_p))
                ts.append((s, pts_t))
            svg_plot(a.plot, [lam for lam, _ in present], ps, ts)
        else:
            print(f"cotrain_report: fewer than two λ runs evaluated; no plot written",
                  file=sys.stderr)
    print(f"cotrain_report: wrote {a.out}")


if __name__ == "__main__":
    try:
        main(sys.argv[1:])
    except CliError as e:
        print(f"cotrain_report: error: {e}", file=sys.stderr)
        sys.exit(1)
