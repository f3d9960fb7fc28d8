#!/usr/bin/python3
"""PyTorch float64 twin of face-api's FaceRecognitionNet (dlib's ResNet-29).

The network maps a 150x150 RGB face chip (values 0..255) to a 128-d
descriptor. It is face-api 1.7.15's faceRecognitionNet (src/faceRecognitionNet/
*.ts), reimplemented here from the same description as the C++ version
(nets/face_recognition.cpp):

  x = (rgb - [122.782, 117.001, 104.298]) / 255
  conv32_down: 7x7 conv stride 2 'valid' + bias, scale layer (x*w + b), ReLU
  max pool 3x3 stride 2 'valid'                                   150 -> 72 -> 35
  14 residual blocks (conv32_1..3, conv64_down, conv64_1..3, conv128_down,
  conv128_1..2, conv256_down, conv256_1..2, conv256_down_out):
    plain: relu(x + conv2(relu(conv1(x))))      both 3x3 'same', stride 1
    down:  conv1 3x3 stride 2 'valid'; the shortcut is avg_pool 2x2/2 'valid'
           of x; where the branch is one row and column smaller it gets a zero
           row at the bottom and a zero column at the right, and where the
           shortcut has fewer channels zeros are appended after them
  mean over the final 2x2 (padded zeros included), then x @ fc [256, 128]
  (no bias, no normalization).

Weights come from face-api's TF.js manifest,
$VKJR2_CACHE_DIR/face-api-1.7.15/model/face_recognition_model-weights_manifest.json
(VKJR2_CACHE_DIR defaults to ~/.cache/vkjr2; scripts/setup puts them there;
VKJR2_FACE_API_DIR, if set, names the model folder instead, as for vkjr2).
Quantized weights are uint8: value = q*scale + min (computed in double, then
rounded to float32 as TF.js stores them, which is also what vkjr2 loads).
Conv filters are HWIO.

Commands:
  fixture OUT.safetensors [--seed S]
      Writes the parity fixture for the C++ network: "input" u8 [2,3,150,150]
      (seeded smooth random images: low-frequency noise plus a +-2 grain,
      integer grey levels),
      "weights" [2,128], "descriptor" [2,128], "loss" [1] =
      sum(weights * descriptor) and "input_grad" [2,3,150,150] = d loss /
      d input, all computed in float64 and stored as float32. The metadata
      holds "face_recognition_model_sha256", the sha256 of the
      face_recognition_model.bin it was made with.
      Committed at tests/data/face_recognition_parity.safetensors and checked by
      tests/nets/face_recognition_test.cpp, so CI needs no PyTorch.
  check [--parity-dir DIR]
      Runs the twin on face-api's own 150x150 inputs (the references that
      scripts/setup writes, default $VKJR2_CACHE_DIR/parity) and prints the
      largest difference from face-api's descriptors.

Run it with Debian's interpreter (/usr/bin/python3, which sees the
python3-torch package). Only the standard library, numpy and torch are used;
safetensors files are written by the small function below.
"""

import argparse
import hashlib
import json
import os
import sys
from pathlib import Path

import numpy as np
import torch
import torch.nn.functional as F

sys.path.insert(0, str(Path(__file__).resolve().parent))
import restorer_torch  # noqa: E402  (the folder's safetensors writer and entry point)

CliError = restorer_torch.CliError
write_safetensors = restorer_torch.write_safetensors

MANIFEST = "face_recognition_model-weights_manifest.json"
MEAN_RGB = (122.782, 117.001, 104.298)
INPUT_SIZE = 150
GRAIN = 2  # grey levels of per-pixel noise in the fixture images
DESCRIPTOR_SIZE = 128
# (name, input channels, output channels, down) in network order.
BLOCKS = [("conv32_1", 32, 32, False), ("conv32_2", 32, 32, False), ("conv32_3", 32, 32, False),
          ("conv64_down", 32, 64, True), ("conv64_1", 64, 64, False),
          ("conv64_2", 64, 64, False), ("conv64_3", 64, 64, False),
          ("conv128_down", 64, 128, True), ("conv128_1", 128, 128, False),
          ("conv128_2", 128, 128, False), ("conv256_down", 128, 256, True),
          ("conv256_1", 256, 256, False), ("conv256_2", 256, 256, False),
          ("conv256_down_out", 256, 256, True)]


# ----------------------------------------------------------------- safetensors

# --------------------------------------------------------------------- weights

def cache_dir():
    """$VKJR2_CACHE_DIR, else ~/.cache/vkjr2."""
    env = os.environ.get("VKJR2_CACHE_DIR")
    return Path(env) if env else Path.home() / ".cache" / "vkjr2"


def model_dir():
    """face-api's model/ folder: $VKJR2_FACE_API_DIR, else the one inside the cache (as vkjr2 looks)."""
    env = os.environ.get("VKJR2_FACE_API_DIR")
    return Path(env) if env else cache_dir() / "face-api-1.7.15" / "model"


def load_tfjs_weights(manifest_path):
    """Reads a TF.js weights manifest and its shards; returns ({name: float64 tensor}, [shard paths])."""
    manifest_path = Path(manifest_path)
    if not manifest_path.is_file():
        raise CliError(f"{manifest_path}: no such file; run scripts/setup (it fetches face-api "
                       "1.7.15's models) or set VKJR2_CACHE_DIR")
    try:
        groups = json.loads(manifest_path.read_text())
    except json.JSONDecodeError as e:
        raise CliError(f"{manifest_path}: not JSON ({e}); re-run scripts/setup") from e
    weights, shards = {}, []
    for group in groups:
        paths = [manifest_path.parent / p for p in group["paths"]]
        for p in paths:
            if not p.is_file():
                raise CliError(f"{p}: shard named by {manifest_path.name} is missing; "
                               "re-run scripts/setup")
        shards += paths
        data = b"".join(p.read_bytes() for p in paths)
        offset = 0
        for w in group["weights"]:
            name, shape = w["name"], [int(d) for d in w["shape"]]
            n = int(np.prod(shape))
            quant = w.get("quantization")
            if w.get("dtype") != "float32":
                raise CliError(f"{manifest_path}: weight {name!r} has dtype {w.get('dtype')!r}; "
                               "this network's weights are all float32")
            if quant is None:
                values = np.frombuffer(data, "<f4", n, offset).astype(np.float64)
                offset += 4 * n
            elif quant.get("dtype") == "uint8":
                q = np.frombuffer(data, np.uint8, n, offset).astype(np.float64)
                # TF.js dequantizes in double and stores float32.
                values = (q * quant["scale"] + quant["min"]).astype(np.float32).astype(np.float64)
                offset += n
            else:
                raise CliError(f"{manifest_path}: weight {name!r} has quantization "
                               f"{quant.get('dtype')!r}; only uint8 is supported")
            if offset > len(data):
                raise CliError(f"{manifest_path}: the shards end inside weight {name!r}; "
                               "they are truncated, re-run scripts/setup")
            weights[name] = torch.from_numpy(values.reshape(shape).copy())
        if offset != len(data):
            raise CliError(f"{manifest_path}: {len(data) - offset} bytes left after the last "
                           "weight; the shards do not match the manifest")
    return weights, shards


def sha256_of(path):
    """The hex sha256 of a file."""
    return hashlib.sha256(Path(path).read_bytes()).hexdigest()


# ----------------------------------------------------------------------- model

class FaceRecognitionNet:
    """face-api's FaceRecognitionNet on float64 tensors; forward() is differentiable."""

    def __init__(self, weights):
        self.w = weights
        self.used = set()
        expected = 5 + sum(8 for _ in BLOCKS)  # conv32_down's 4, fc, 2 conv layers x 4 per block
        if len(weights) != expected:
            raise CliError(f"the manifest holds {len(weights)} weights, this network uses "
                           f"{expected}; is it face_recognition_model?")

    def take(self, name, shape):
        """The weight `name`, checked against `shape`."""
        if name not in self.w:
            raise CliError(f"weight {name!r} is missing from the manifest")
        t = self.w[name]
        if list(t.shape) != list(shape):
            raise CliError(f"weight {name!r} is {list(t.shape)}, expected {list(shape)}")
        self.used.add(name)
        return t

    def conv_layer(self, x, prefix, kernel, cin, cout, down, relu):
        """conv + bias, then the scale layer x*w + b, then ReLU if `relu` (convLayer.ts)."""
        filters = self.take(f"{prefix}/conv/filters", [kernel, kernel, cin, cout])
        bias = self.take(f"{prefix}/conv/bias", [cout])
        scale = self.take(f"{prefix}/scale/weights", [cout])
        shift = self.take(f"{prefix}/scale/biases", [cout])
        weight = filters.permute(3, 2, 0, 1)  # HWIO -> OIHW
        if down:  # stride 2, 'valid'
            y = F.conv2d(x, weight, bias, stride=2)
        else:  # stride 1, 'same' (odd kernel: the same padding on every side)
            y = F.conv2d(x, weight, bias, padding=kernel // 2)
        y = y * scale.view(1, -1, 1, 1) + shift.view(1, -1, 1, 1)
        return F.relu(y) if relu else y

    def residual(self, x, name, cin, cout, down):
        """residual / residualDown (residualLayer.ts)."""
        y = self.conv_layer(x, f"{name}/conv1", 3, cin, cout, down, relu=True)
        y = self.conv_layer(y, f"{name}/conv2", 3, cout, cout, False, relu=False)
        shortcut = x
        if down:
            shortcut = F.avg_pool2d(x, 2, 2)
            dh, dw = shortcut.shape[2] - y.shape[2], shortcut.shape[3] - y.shape[3]
            if (dh, dw) != (0, 0):
                assert (dh, dw) == (1, 1), (name, shortcut.shape, y.shape)
                y = F.pad(y, (0, 1, 0, 1))  # a zero row at the bottom, a zero column at the right
            if shortcut.shape[1] != y.shape[1]:
                zeros = shortcut.new_zeros(shortcut.shape)
                shortcut = torch.cat([shortcut, zeros], dim=1)
        return F.relu(shortcut + y)

    def forward(self, rgb):
        """rgb [N, 3, 150, 150] in 0..255 -> descriptors [N, 128]."""
        if rgb.ndim != 4 or list(rgb.shape[1:]) != [3, INPUT_SIZE, INPUT_SIZE]:
            raise CliError(f"input is {list(rgb.shape)}, expected [N, 3, 150, 150]")
        self.used.clear()
        mean = torch.tensor(MEAN_RGB, dtype=rgb.dtype).view(1, 3, 1, 1)
        x = (rgb - mean) / 255
        x = self.conv_layer(x, "conv32_down", 7, 3, 32, True, relu=True)
        x = F.max_pool2d(x, 3, 2)
        for name, cin, cout, down in BLOCKS:
            x = self.residual(x, name, cin, cout, down)
        x = x.mean(dim=(2, 3))
        out = x @ self.take("fc", [256, DESCRIPTOR_SIZE])
        unused = sorted(set(self.w) - self.used)
        if unused:
            raise CliError(f"the manifest holds weights this network does not use: {unused}")
        return out


def load_net(dtype=torch.float64):
    """The network from the cached face-api model; returns (net, path of the .bin shard)."""
    weights, shards = load_tfjs_weights(model_dir() / MANIFEST)
    if len(shards) != 1:
        raise CliError(f"{MANIFEST} names {len(shards)} shards; face-api 1.7.15 ships one "
                       "(face_recognition_model.bin)")
    return FaceRecognitionNet({k: v.to(dtype) for k, v in weights.items()}), shards[0]


# -------------------------------------------------------------------- commands

def smooth_images(n, seed):
    """n seeded RGB images [n, 3, 150, 150] of low-frequency noise, integers in 0..255.

    Four octaves of bicubically upsampled uniform noise (grid cells 3, 6, 12
    and 25 across, amplitudes halving), stretched per image to 2..253, plus a
    grain of uniform integers in [-2, 2] per pixel. Without the grain, flat
    regions round to plateaus of equal values, whose equal 7x7 patches tie in
    the first max pool (which input gets the gradient is then a convention).
    """
    g = torch.Generator().manual_seed(seed)
    img = torch.zeros(n, 3, INPUT_SIZE, INPUT_SIZE, dtype=torch.float64)
    for cells, amplitude in ((3, 1.0), (6, 0.5), (12, 0.25), (25, 0.125)):
        grid = 2 * torch.rand(n, 3, cells + 1, cells + 1, generator=g, dtype=torch.float64) - 1
        img += amplitude * F.interpolate(grid, size=(INPUT_SIZE, INPUT_SIZE), mode="bicubic",
                                         align_corners=True)
    lo = img.amin(dim=(1, 2, 3), keepdim=True)
    hi = img.amax(dim=(1, 2, 3), keepdim=True)
    img = torch.round((img - lo) / (hi - lo) * (255 - 2 * GRAIN)) + GRAIN
    grain = torch.randint(-GRAIN, GRAIN + 1, img.shape, generator=g, dtype=torch.float64)
    return (img + grain).to(torch.uint8)


def descriptor_and_grad(net, rgb, weights):
    """(descriptor, loss, d loss / d rgb) for loss = sum(weights * net(rgb))."""
    x = rgb.clone().requires_grad_(True)
    d = net.forward(x)
    loss = (weights * d).sum()
    loss.backward()
    return d.detach(), loss.detach(), x.grad


def error_stats(got, want):
    """|got - want| / max |want|: its median, 90th and 99th percentiles and max, and the relative L2 error."""
    err = (got.double() - want).abs().flatten()
    rel = err / want.abs().max()
    q = torch.quantile(rel, torch.tensor([0.5, 0.9, 0.99], dtype=torch.float64)).tolist()
    return (f"median {q[0]:.2g}, p90 {q[1]:.2g}, p99 {q[2]:.2g}, max {rel.max().item():.2g}; "
            f"relative L2 {(err.norm() / want.norm()).item():.2g}")


def cmd_fixture(args):
    """Writes the C++ parity fixture (float64 reference, stored as float32)."""
    net64, shard = load_net(torch.float64)
    net32, _ = load_net(torch.float32)
    pixels = smooth_images(2, args.seed)
    g = torch.Generator().manual_seed(args.seed + 1)
    weights = torch.randn(2, DESCRIPTOR_SIZE, generator=g, dtype=torch.float32)

    d64, loss64, grad64 = descriptor_and_grad(net64, pixels.double(), weights.double())
    d32, _, grad32 = descriptor_and_grad(net32, pixels.float(), weights)
    tensors = {"input": pixels.numpy(), "weights": weights.numpy(),
               "descriptor": d64.float().numpy(), "loss": loss64.reshape(1).float().numpy(),
               "input_grad": grad64.float().numpy()}
    meta = {"network": "face-api FaceRecognitionNet", "face_api": "1.7.15",
            "face_recognition_model_sha256": sha256_of(shard),
            "loss": "sum(weights * descriptor)", "seed": str(args.seed),
            "generator": "tools/face_recognition_torch.py fixture"}
    write_safetensors(args.out, tensors, meta)
    print(f"wrote {args.out}: {Path(args.out).stat().st_size} bytes, loss {loss64.item():.9g}, "
          f"descriptor norms {[round(v, 4) for v in d64.norm(dim=1).tolist()]}, "
          f"max |input_grad| {grad64.abs().max().item():.3g}\n"
          f"PyTorch float32 vs float64, |diff| / max |value|:\n"
          f"  descriptor {error_stats(d32, d64)}\n  input_grad {error_stats(grad32, grad64)}")


def cmd_check(args):
    """Compares the twin's descriptors with face-api's on its own 150x150 inputs."""
    parity = Path(args.parity_dir) if args.parity_dir else cache_dir() / "parity"
    index_path = parity / "index.json"
    if not index_path.is_file():
        raise CliError(f"{index_path}: no such file; run scripts/setup (it writes the face-api "
                       "references) or pass --parity-dir")
    index = json.loads(index_path.read_text())
    inputs, want = [], []
    for image in index["images"]:
        for det in image["detections"]:
            hwc = np.load(parity / det["recognition_150"])
            inputs.append(torch.from_numpy(hwc.astype(np.float64)).permute(2, 0, 1))
            want.append(det["descriptor_150"])
    if not inputs:
        raise CliError(f"{index_path} lists no faces")
    net, _ = load_net(torch.float64)
    with torch.no_grad():
        got = net.forward(torch.stack(inputs))
    diff = (got - torch.tensor(want, dtype=torch.float64)).abs().max().item()
    print(f"{len(inputs)} faces: max |descriptor - face-api| = {diff:.3g}")


def build_parser():
    """The argparse parser with the fixture and check subcommands."""
    parser = argparse.ArgumentParser(description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    sub = parser.add_subparsers(dest="command", required=True)
    p = sub.add_parser("fixture", help="write the C++ parity fixture")
    p.add_argument("out", help="output .safetensors path")
    p.add_argument("--seed", type=int, default=7, help="seed of the images and weights (default 7)")
    p.set_defaults(func=cmd_fixture)
    p = sub.add_parser("check", help="compare with face-api's descriptors on its own inputs")
    p.add_argument("--parity-dir", help="face-api references (default $VKJR2_CACHE_DIR/parity)")
    p.set_defaults(func=cmd_check)
    return parser


def main(argv=None):
    """Entry point."""
    return restorer_torch.run_main(build_parser(), argv)


if __name__ == "__main__":
    sys.exit(main())
