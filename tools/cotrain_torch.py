#!/usr/bin/python3
"""PyTorch peer of vkjr2's JR² co-training step (jr2/cotrain.hpp, `vkjr2 bench cotrain`).

One restore-first co-training step on a batch of B clips of T frames, window
W² (input [B, 3T, W, W] in 0..1), timed stage by stage on the CPU:

  student   out = R_s(y)                                   (recorded for backward)
  teacher   target = R_t(y)                                (no_grad)
  align + recognizer + head
            pixels = 255 * (relu(out) - relu(out - 1))     (255 * clamp(out, 0, 1))
            crops = grid_sample(pixels, affine_grid(theta, [B, 3, 150, 150]))
                    (bilinear, zeros padding, align_corners=False)
            d = G(crops)                                   (face-api's recognizer, frozen)
            L = CE(AdaFace(d, labels), labels) + lambda * mean |out - target|
  backward  L.backward()  (to the student's parameters and the head's kernel)
  optimizer Adam(lr 1e-4).step(), zero_grad()

The similarity thetas [B, 2, 3] are constants: vkjr2 computes them on the host
from landmarks; this peer takes them from --thetas (vkjr2 passes its own) or
makes them with the same recipe from --seed. Labels are b % classes.

The networks: the restorer of tools/restorer_torch.py, with the weights of
--restorer when given (a vkjr2 restorer file; the teacher and the student's
start, as `vkjr2 cotrain` does), else a fresh one of --frames/--width/
--enc/--middle/--dec (random initialization: for timing only the shapes
matter); the recognizer of tools/face_recognition_torch.py in float32 with
face-api's weights ($VKJR2_CACHE_DIR or ~/.cache/vkjr2,
face-api-1.7.15/model), which never require a gradient (frozen). The AdaFace
head is below (m 0.4, h 0.333, s 64, EMA t_alpha 0.01, eps 1e-3, norms
clipped to [0.001, 100] and detached), as tools/adaface_torch.py and the
official head compute it.

Commands:
  bench [--batch --frames --window --classes --lambda --threads --repeat
         --restorer PATH --thetas a,b,... --seed S]
      Times the step's stages (median seconds over --repeat steps after one
      warm-up) and prints one JSON line: "stages" {student, teacher, align_
      recognize_head, backward, optimizer}, "step_s" (median of the steps'
      totals), the configuration, the process's peak resident memory and the
      torch version.

Run it with Debian's interpreter (/usr/bin/python3, which sees the
python3-torch package).
"""

import argparse
import copy
import json
import math
import resource
import statistics
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

import numpy as np  # noqa: E402
import torch  # noqa: E402
import torch.nn.functional as F  # noqa: E402
from torch import nn  # noqa: E402

import face_recognition_torch  # noqa: E402
import restorer_torch  # noqa: E402

CliError = restorer_torch.CliError
CROP = face_recognition_torch.INPUT_SIZE  # 150
DESCRIPTOR = face_recognition_torch.DESCRIPTOR_SIZE  # 128
ADAM_LR = 1e-4
STAGES = ("student", "teacher", "align_recognize_head", "backward", "optimizer")


class AdaFaceHead(nn.Module):
    """The official AdaFace head (mk-minchul/AdaFace head.py) on raw embeddings [B, D]."""

    def __init__(self, dim, classes, m=0.4, h=0.333, s=64.0, t_alpha=0.01, eps=1e-3):
        super().__init__()
        kernel = 2 * torch.rand(dim, classes) - 1
        self.kernel = nn.Parameter(kernel / kernel.norm(dim=0, keepdim=True))
        self.register_buffer("batch_mean", torch.full((1,), 20.0))
        self.register_buffer("batch_std", torch.full((1,), 100.0))
        self.m, self.h, self.s, self.t_alpha, self.eps = m, h, s, t_alpha, eps

    def forward(self, embeddings, labels):
        """embeddings [B, D], labels int64 [B] -> margin logits [B, C]."""
        norms = embeddings.norm(dim=1, keepdim=True)
        cos = (embeddings / norms) @ (self.kernel / self.kernel.norm(dim=0, keepdim=True))
        cos = cos.clamp(-1 + self.eps, 1 - self.eps)
        safe = norms.clip(0.001, 100).detach()
        if self.training:
            with torch.no_grad():
                a = self.t_alpha
                self.batch_mean.mul_(1 - a).add_(a * safe.mean())
                self.batch_std.mul_(1 - a).add_(a * safe.std(unbiased=True))
        scaler = (self.h * (safe - self.batch_mean) / (self.batch_std + self.eps)).clip(-1, 1)
        onehot = F.one_hot(labels, cos.shape[1]).to(cos.dtype)
        theta = (cos.acos() - onehot * (self.m * scaler)).clip(self.eps, math.pi - self.eps)
        return self.s * (theta.cos() - onehot * (self.m + self.m * scaler))


def make_thetas(batch, window, seed):
    """theta [B, 2, 3] of 150² crops of a face centred in a W² window (align_corners=False).

    Per clip a similarity from the crop to the window: rotation within +-10
    degrees, the crop spanning 0.8 W (times 0.9..1.1), its centre within +-4
    pixels of the window's (pixel centres at integer coordinates). The same
    recipe as bench/cotrain_bench.cpp, with numpy's generator.
    """
    rng = np.random.default_rng(seed)
    thetas = []
    for _ in range(batch):
        angle = math.radians(rng.uniform(-10, 10))
        scale = 0.8 * window / CROP * rng.uniform(0.9, 1.1)
        cx = (window - 1) / 2 + rng.uniform(-4, 4)
        cy = (window - 1) / 2 + rng.uniform(-4, 4)
        a, b = scale * math.cos(angle), scale * math.sin(angle)
        # Crop pixel (u + 1)·150/2 − 0.5 of normalized u goes to window pixel
        # p = S·(crop − centre) + (cx, cy), normalized (2p + 1)/W − 1: the crop's
        # centre lands on (cx, cy).
        k = CROP / window
        thetas.append([[a * k, -b * k, (2 * cx + 1) / window - 1],
                       [b * k, a * k, (2 * cy + 1) / window - 1]])
    return torch.tensor(thetas, dtype=torch.float32)


def parse_thetas(text, batch):
    """--thetas: 6·B comma-separated floats -> [B, 2, 3]."""
    try:
        values = [float(v) for v in text.split(",")]
    except ValueError:
        raise CliError(f"--thetas is not comma-separated numbers: {text[:60]!r}") from None
    if len(values) != 6 * batch:
        raise CliError(f"--thetas has {len(values)} values; give 6 per clip ({6 * batch} "
                       f"for --batch {batch})")
    return torch.tensor(values, dtype=torch.float32).view(batch, 2, 3)


def to_pixels(x):
    """255 * clamp(x, 0, 1), as relu(x) - relu(x - 1) (the C++ graph)."""
    return 255 * (F.relu(x) - F.relu(x - 1))


def cmd_bench(args):
    """Times the co-training step's stages; prints JSON."""
    if args.batch < 2:
        raise CliError(f"--batch {args.batch}: AdaFace's norm statistics need at least 2 clips")
    torch.set_num_threads(args.threads)
    torch.manual_seed(args.seed)
    if args.restorer:
        teacher = restorer_torch.load_restorer(args.restorer)
        weights = "restorer file"
    else:
        enc = restorer_torch.parse_ints(args.enc, "--enc")
        dec = restorer_torch.parse_ints(args.dec, "--dec")
        teacher = restorer_torch.Restorer(args.frames, args.width, enc, args.middle, dec)
        weights = "random initialization"
    if args.window % 2 ** teacher.levels:
        raise CliError(f"--window {args.window} is not a multiple of {2 ** teacher.levels} "
                       "(2^levels)")
    student = copy.deepcopy(teacher)  # the student starts as the teacher, as vkjr2 cotrain
    teacher.eval()
    for p in teacher.parameters():
        p.requires_grad_(False)
    student.train()
    recognizer, _ = face_recognition_torch.load_net(torch.float32)
    head = AdaFaceHead(DESCRIPTOR, args.classes)
    head.train()
    optim = torch.optim.Adam(list(student.parameters()) + list(head.parameters()), lr=ADAM_LR)

    frames = teacher.frames
    inp = torch.rand(args.batch, 3 * frames, args.window, args.window)
    thetas = (parse_thetas(args.thetas, args.batch) if args.thetas
              else make_thetas(args.batch, args.window, args.seed))
    labels = torch.arange(args.batch) % args.classes

    def step():
        times = {}
        t0 = time.perf_counter()
        out = student(inp)
        t1 = time.perf_counter()
        times["student"] = t1 - t0
        with torch.no_grad():
            target = teacher(inp)
        t2 = time.perf_counter()
        times["teacher"] = t2 - t1
        pixels = to_pixels(out)
        grid = F.affine_grid(thetas, [args.batch, 3, CROP, CROP], align_corners=False)
        crops = F.grid_sample(pixels, grid, mode="bilinear", padding_mode="zeros",
                              align_corners=False)
        logits = head(recognizer.forward(crops), labels)
        loss = F.cross_entropy(logits, labels) + args.lam * F.l1_loss(out, target)
        t3 = time.perf_counter()
        times["align_recognize_head"] = t3 - t2
        loss.backward()
        t4 = time.perf_counter()
        times["backward"] = t4 - t3
        optim.step()
        optim.zero_grad()
        t5 = time.perf_counter()
        times["optimizer"] = t5 - t4
        times["step"] = t5 - t0
        if not math.isfinite(loss.item()):
            raise CliError(f"the loss became {loss.item()}; the peer's graph is broken")
        return times

    step()  # warm-up
    runs = [step() for _ in range(args.repeat)]
    result = {"stages": {k: statistics.median(r[k] for r in runs) for k in STAGES},
              "step_s": statistics.median(r["step"] for r in runs),
              "batch": args.batch, "frames": frames, "window": args.window,
              "classes": args.classes, "lambda": args.lam, "threads": args.threads,
              "repeat": args.repeat, "student_weights": weights,
              "student_params": sum(p.numel() for p in student.parameters()),
              "thetas": "--thetas" if args.thetas else f"seed {args.seed}",
              "max_rss_bytes": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024,
              "torch": torch.__version__}
    print(json.dumps(result))


def build_parser():
    """The argparse parser with the bench subcommand."""
    parser = argparse.ArgumentParser(description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    sub = parser.add_subparsers(dest="command", required=True)
    p = sub.add_parser("bench", help="time the co-training step's stages on the CPU, print JSON")
    p.add_argument("--batch", type=int, default=8, help="clips per step B (default 8)")
    p.add_argument("--window", type=int, default=128, help="window side W (default 128)")
    p.add_argument("--classes", type=int, default=19, help="AdaFace classes (default 19)")
    p.add_argument("--lambda", dest="lam", type=float, default=1000.0,
                   help="self-distillation weight (default 1000, vkjr2 cotrain's)")
    p.add_argument("--restorer", help="a vkjr2 restorer file (else a fresh network of the "
                   "options below)")
    p.add_argument("--frames", type=int, default=8, help="input frames T (default 8)")
    p.add_argument("--width", type=int, default=16, help="base width w (default 16)")
    p.add_argument("--enc", default="1,1,1", help="encoder blocks per level (default 1,1,1)")
    p.add_argument("--middle", type=int, default=1, help="middle blocks (default 1)")
    p.add_argument("--dec", default="1,1,1",
                   help="decoder blocks per level, deepest first (default 1,1,1)")
    p.add_argument("--thetas", help="6·B comma-separated floats, theta [B, 2, 3] (default: made "
                   "from --seed)")
    p.add_argument("--seed", type=int, default=1, help="seed of the input, head and thetas "
                   "(default 1)")
    p.add_argument("--threads", type=int, default=2, help="torch.set_num_threads (default 2)")
    p.add_argument("--repeat", type=int, default=5,
                   help="timed steps after one warm-up; medians are reported (default 5)")
    p.set_defaults(func=cmd_bench)
    return parser


def main(argv=None):
    """Entry point."""
    return restorer_torch.run_main(build_parser(), argv)


if __name__ == "__main__":
    sys.exit(main())
