#!/usr/bin/python3
"""PyTorch float64 reference of the AdaFace margin head, for vkjr2's nets::AdaFaceHead.

AdaFace (Kim et al., "AdaFace: Quality Adaptive Margin for Face Recognition",
CVPR 2022), as the official head (github.com/mk-minchul/AdaFace, head.py)
computes it. The backbone there returns unit embeddings and their norms; here
the head takes the raw embeddings z [B, D] and splits them the same way:

  n_b = |z_b|,  cos = clamp((z_b / n_b) . (W_j / |W_j|), -1 + eps, 1 - eps)
  safe_b = clip(n_b, 0.001, 100), detached
  training: batch_mean <- t_alpha * mean(safe) + (1 - t_alpha) * batch_mean
            batch_std  <- t_alpha * std(safe)  + (1 - t_alpha) * batch_std   (unbiased std)
            (updated before the scaler is formed)
  scaler_b = clip(h * (safe_b - batch_mean) / (batch_std + eps), -1, 1)
  label column: theta' = clip(arccos(cos) - m * scaler_b, eps, pi - eps)   (g_angle = -m * scaler)
                logit = s * (cos(theta') - (m + m * scaler_b))            (g_add = m + m * scaler)
  other columns: s * cos(clip(arccos(cos), eps, pi - eps))
  loss = cross_entropy(logits, labels), the mean over the batch

with m = 0.4, h = 0.333, s = 64, t_alpha = 0.01, eps = 1e-3. W is "kernel"
[D, C]; the buffers start at batch_mean 20 and batch_std 100 in the official
module.

Commands:
  fixture OUT.safetensors [--seed S]
      Writes the parity fixture for the C++ head: a kernel [16, 5], the running
      statistics to start from, and 3 seeded batches (embeddings [6, 16] with
      norms from 1.5 to 120, labels) run one after the other in training mode.
      For each call it stores the logits, the cross-entropy loss, its
      gradients d_embeddings and d_kernel, the margin scaler and batch_mean /
      batch_std after the call, all computed in float64 and stored as float32.
      Committed at tests/data/adaface_parity.safetensors and checked by
      tests/nets/adaface_test.cpp, so CI needs no PyTorch.

Run it with Debian's interpreter (/usr/bin/python3, which sees the
python3-torch package). Only the standard library, numpy and torch are used;
safetensors files are written by the small function below.
"""

import argparse
import math
import sys
from pathlib import Path

import numpy as np
import torch
import torch.nn.functional as F

sys.path.insert(0, str(Path(__file__).resolve().parent))
import restorer_torch  # noqa: E402  (the folder's safetensors writer and entry point)

CliError = restorer_torch.CliError
write_safetensors = restorer_torch.write_safetensors

OPTIONS = {"m": 0.4, "h": 0.333, "s": 64.0, "t_alpha": 0.01, "eps": 1e-3}
BATCH, DIM, CLASSES, CALLS = 6, 16, 5, 3
# Norms of each batch's embeddings (shuffled per batch): with the running
# statistics below they put the scaler at both clips and inside, and 120 is
# clipped to 100 before it enters the statistics.
NORMS = (1.5, 8.0, 14.0, 21.0, 40.0, 120.0)
# Where the running statistics start. The official start (20, 100) would keep
# every scaler within 0.09 of 0 for these norms (and any norm <= 100 within
# 0.27): no clip. A trained backbone's statistics are tighter.
START_MEAN, START_STD = 18.0, 5.0


class AdaFaceHead:
    """The official head's arithmetic in the dtype of its tensors; forward() is differentiable."""

    def __init__(self, kernel, batch_mean, batch_std, m, h, s, t_alpha, eps):
        self.kernel = kernel.clone().requires_grad_(True)
        self.batch_mean = torch.tensor([batch_mean], dtype=kernel.dtype)
        self.batch_std = torch.tensor([batch_std], dtype=kernel.dtype)
        self.m, self.h, self.s, self.t_alpha, self.eps = m, h, s, t_alpha, eps

    def forward(self, embeddings, labels, training=True):
        """embeddings [B, D], labels int64 [B] -> (logits [B, C], margin scaler [B], kink distance).

    The kink distance is how close any clamp or clip came to switching: the
    smallest distance of the unclamped cosines from +-(1 - eps), of the
    unclipped scalers from +-1 and of the label columns' unclipped angles
    from eps and pi - eps.
    """
        norms = embeddings.norm(dim=1, keepdim=True)
        unit = embeddings / norms
        kernel_unit = self.kernel / self.kernel.norm(dim=0, keepdim=True)
        cos_raw = unit @ kernel_unit
        cos = cos_raw.clamp(-1 + self.eps, 1 - self.eps)

        safe = norms.clip(0.001, 100).detach()
        if training:
            with torch.no_grad():
                a = self.t_alpha
                self.batch_mean = a * safe.mean() + (1 - a) * self.batch_mean
                self.batch_std = a * safe.std(unbiased=True) + (1 - a) * self.batch_std
        scaler_raw = self.h * (safe - self.batch_mean) / (self.batch_std + self.eps)
        scaler = scaler_raw.clip(-1, 1)

        onehot = F.one_hot(labels, cos.shape[1]).to(cos.dtype)
        g_angle = -self.m * scaler
        theta_raw = cos.acos() + onehot * g_angle
        theta = theta_raw.clip(self.eps, math.pi - self.eps)
        g_add = self.m + self.m * scaler
        with torch.no_grad():
            label_theta = theta_raw.gather(1, labels[:, None])
            kink = min((cos_raw.abs() - (1 - self.eps)).abs().min().item(),
                       (scaler_raw.abs() - 1).abs().min().item(),
                       (label_theta - self.eps).abs().min().item(),
                       (label_theta - (math.pi - self.eps)).abs().min().item())
        return self.s * (theta.cos() - onehot * g_add), scaler.flatten(), kink


def rotate_towards(a, b, angle):
    """The unit vector at `angle` rad from unit a, in the plane of a and b, on b's side."""
    off = b - (b @ a) * a
    return math.cos(angle) * a + math.sin(angle) * off / off.norm()


def make_kernel(seed):
    """W [D, C]: the official initialisation (uniform(-1, 1), unit columns), except
    that the last column is put 0.06 rad from the one before (two near-identical
    classes, for the clamped cosine in make_batches).
    """
    g = torch.Generator().manual_seed(seed)
    kernel = 2 * torch.rand(DIM, CLASSES, generator=g, dtype=torch.float64) - 1
    kernel /= kernel.norm(dim=0, keepdim=True)
    kernel[:, -1] = rotate_towards(kernel[:, -2], kernel[:, -1], 0.06)
    return kernel.float().double()  # stored as float32: both sides start from the same values


def make_batches(seed, kernel):
    """CALLS seeded batches: ([B, D] float64 embeddings, [B] int64 labels) each.

    Directions are Gaussian, except for one row in each of batches 1 and 2,
    placed so that a clamp or clip is active where the loss still has a
    gradient (a clamped label logit that wins the softmax has almost none):
    - batch 1, the largest norm (scaler clipped at 1): 0.2 rad from its class
      centre towards the nearest other centre. The angle minus the margin 0.4
      clips at eps; the other class wins.
    - batch 2, the smallest norm (scaler near -1), label C-2: 0.02 rad from
      its centre, away from class C-1 (0.06 rad from C-2): cos > 1 - eps
      clamps, and class C-1 (cos 0.997) outscores the margin-lowered label.
    """
    g = torch.Generator().manual_seed(seed)
    centres = kernel / kernel.norm(dim=0, keepdim=True)
    batches = []
    for call in range(CALLS):
        labels = torch.randint(0, CLASSES, (BATCH,), generator=g)
        direction = torch.randn(BATCH, DIM, generator=g, dtype=torch.float64)
        norms = torch.tensor(NORMS, dtype=torch.float64)[torch.randperm(BATCH, generator=g)]
        if call == 1:
            row = int((norms == max(NORMS)).nonzero()[0])
            label = int(labels[row])
            similarity = centres[:, label] @ centres
            similarity[label] = -2
            other = int(similarity.argmax())
            direction[row] = rotate_towards(centres[:, label], centres[:, other], 0.2)
        elif call == 2:
            row = int((norms == min(NORMS)).nonzero()[0])
            labels[row] = CLASSES - 2
            direction[row] = rotate_towards(centres[:, -2], -centres[:, -1], 0.02)
        direction /= direction.norm(dim=1, keepdim=True)
        z = (direction * norms[:, None]).float().double()  # stored as float32
        batches.append((z, labels))
    return batches


def run_calls(head, batches):
    """The training-mode calls in order; per call a dict of float64 results."""
    out = []
    for z, labels in batches:
        z = z.clone().requires_grad_(True)
        head.kernel.grad = None
        logits, scaler, kink = head.forward(z, labels)
        loss = F.cross_entropy(logits, labels)
        loss.backward()
        out.append({"logits": logits.detach(), "loss": loss.detach().reshape(1),
                    "d_embeddings": z.grad, "d_kernel": head.kernel.grad.clone(),
                    "margin_scaler": scaler, "batch_mean": head.batch_mean.clone(),
                    "batch_std": head.batch_std.clone(), "kink": kink})
    return out


def cmd_fixture(args):
    """Writes the C++ parity fixture (float64 reference, stored as float32)."""
    kernel = make_kernel(args.seed)
    batches = make_batches(args.seed + 1, kernel)

    calls64 = run_calls(AdaFaceHead(kernel, START_MEAN, START_STD, **OPTIONS), batches)
    calls32 = run_calls(AdaFaceHead(kernel.float(), START_MEAN, START_STD, **OPTIONS),
                        [(z.float(), y) for z, y in batches])
    scalers = torch.cat([c["margin_scaler"] for c in calls64])
    clipped = int((scalers.abs() == 1).sum())
    if clipped == 0 or clipped == scalers.numel():
        raise CliError(f"seed {args.seed}: {clipped} of {scalers.numel()} margin scalers clip; "
                       "the fixture needs both clipped and interior ones, try another --seed")
    kink = min(c["kink"] for c in calls64)
    if kink < 1e-4:  # float32 errors here are ~1e-7
        raise CliError(f"seed {args.seed}: a clamp or clip sits {kink:.2g} from switching, where "
                       "float32 could fall on its other side; try another --seed")

    def stack(key):
        return torch.stack([c[key] for c in calls64]).float().numpy()

    tensors = {"kernel": kernel.float().numpy(),
               "embeddings": torch.stack([z for z, _ in batches]).float().numpy(),
               "labels": torch.stack([y for _, y in batches]).to(torch.int32).numpy(),
               "batch_mean_init": np.array([START_MEAN], np.float32),
               "batch_std_init": np.array([START_STD], np.float32)}
    for key in ("logits", "loss", "d_embeddings", "d_kernel", "margin_scaler", "batch_mean",
                "batch_std"):
        tensors[key] = stack(key)
    meta = {"head": "AdaFace (mk-minchul/AdaFace head.py)", "loss": "cross_entropy (mean)",
            "calls": str(CALLS), "seed": str(args.seed),
            "generator": "tools/adaface_torch.py fixture"}
    meta.update({k: repr(v) for k, v in OPTIONS.items()})
    write_safetensors(args.out, tensors, meta)

    print(f"wrote {args.out}: {Path(args.out).stat().st_size} bytes; losses "
          f"{[round(c['loss'].item(), 6) for c in calls64]}; {clipped} of {scalers.numel()} "
          f"scalers clipped; nearest clamp/clip {kink:.3g} from switching; batch_mean {calls64[-1]['batch_mean'].item():.6g}, batch_std "
          f"{calls64[-1]['batch_std'].item():.6g}\nPyTorch float32 vs float64, max |diff| / "
          "max |value| over the calls:")
    for key in ("logits", "loss", "d_embeddings", "d_kernel", "batch_mean", "batch_std"):
        want = torch.stack([c[key] for c in calls64])
        got = torch.stack([c[key] for c in calls32]).double()
        print(f"  {key}: {((got - want).abs().max() / want.abs().max()).item():.3g}")


def build_parser():
    """The argparse parser with the fixture subcommand."""
    parser = argparse.ArgumentParser(description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    sub = parser.add_subparsers(dest="command", required=True)
    p = sub.add_parser("fixture", help="write the C++ parity fixture")
    p.add_argument("out", help="output .safetensors path")
    p.add_argument("--seed", type=int, default=3, help="seed of the kernel and batches (default 3)")
    p.set_defaults(func=cmd_fixture)
    return parser


def main(argv=None):
    """Entry point."""
    return restorer_torch.run_main(build_parser(), argv)


if __name__ == "__main__":
    sys.exit(main())
