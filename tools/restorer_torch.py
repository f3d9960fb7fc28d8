#!/usr/bin/python3
"""PyTorch reference of the vkjr2 image restorer (a NAFNet-style U-Net).

The restorer follows NAFNet (Chen et al., "Simple Baselines for Image
Restoration", ECCV 2022): LayerNorm2d, SimpleGate, simplified channel
attention, 2x2 strided-conv downsampling, 1x1 conv + PixelShuffle upsampling
and additive skips. It takes T RGB frames stacked on channels ([N, 3T, H, W],
frame f = channels 3f..3f+2, H and W multiples of 2^L) and predicts the
reference frame r = T // 2 as a residual: output [N, 3, H, W].

Tensor names are the safetensors names used by vkjr2. A restorer file has the
metadata "format": "vkjr2-checkpoint-1" (nets/checkpoint.hpp), "network":
"vkjr2.restorer", "frames", "width", "middle_blocks"
(decimal strings), "enc_blocks" and "dec_blocks" (comma-separated ints).
Tensors may carry the prefix "model." (a training checkpoint); tensors that
are not model parameters are ignored.

Commands:
  fixture OUT.safetensors [--seed S]
      Writes the parity fixture for the C++ restorer: a tiny model (frames 2,
      width 4, enc 1,1, middle 1, dec 1,1) with random weights, an input, a
      target, the float64 forward output, the Charbonnier loss, its gradients
      and the weights after one Adam step. The fixture is committed at
      tests/data/restorer_parity.safetensors and checked by a C++ test, so CI
      needs no PyTorch.
  run WEIGHTS.safetensors IN.safetensors OUT.safetensors
      Runs a (vkjr2-trained) restorer in float32 on IN's tensor "input" and
      writes OUT with the tensor "output".
  bench [--frames --width --enc --middle --dec --size --batch --threads --repeat]
      Times CPU inference and one training step (forward, Charbonnier loss,
      backward, Adam) and prints JSON; the PyTorch peer of the C++ benchmark.

Run it with Debian's interpreter (/usr/bin/python3, which sees the
python3-torch package). Only the standard library, numpy and torch are used; safetensors files are
read and written by the small functions below.
"""

import argparse
import copy
import json
import statistics
import struct
import sys
import time
from pathlib import Path

import numpy as np
import torch
import torch.nn.functional as F
from torch import nn

NETWORK = "vkjr2.restorer"
FORMAT = "vkjr2-checkpoint-1"
DTYPES = {"F32": np.dtype("<f4"), "U32": np.dtype("<u4"), "I32": np.dtype("<i4"),
          "U8": np.dtype("u1")}
CHARBONNIER_EPS = 1e-3
ADAM_LR = 1e-3


class CliError(Exception):
    """A user-facing error: what went wrong and how to fix it."""


# ----------------------------------------------------------------- safetensors

def read_safetensors(path):
    """Reads a safetensors file; returns ({name: numpy array}, {str: str} metadata)."""
    path = Path(path)
    if not path.is_file():
        raise CliError(f"{path}: no such file (check the path)")
    data = path.read_bytes()
    if len(data) < 8:
        raise CliError(f"{path}: too short to be a safetensors file")
    (n,) = struct.unpack("<Q", data[:8])
    if 8 + n > len(data):
        raise CliError(f"{path}: header length {n} runs past the end of the file")
    try:
        header = json.loads(data[8:8 + n].decode("utf-8"))
    except (UnicodeDecodeError, json.JSONDecodeError) as e:
        raise CliError(f"{path}: header is not JSON ({e}); pass a safetensors file") from e
    metadata = header.pop("__metadata__", None) or {}
    body = memoryview(data)[8 + n:]
    tensors = {}
    for name, info in header.items():
        try:
            dtype = DTYPES.get(info["dtype"])
            shape = [int(d) for d in info["shape"]]
            begin, end = (int(o) for o in info["data_offsets"])
        except (KeyError, TypeError, ValueError) as e:
            raise CliError(f"{path}: tensor {name!r} has a malformed header entry ({e!r})") from e
        if dtype is None:
            raise CliError(f"{path}: tensor {name!r} has dtype {info['dtype']!r}; "
                           f"only {', '.join(DTYPES)} are supported")
        if not 0 <= begin <= end <= len(body) or end - begin != dtype.itemsize * int(np.prod(shape)):
            raise CliError(f"{path}: tensor {name!r} has bad data_offsets {[begin, end]}")
        tensors[name] = np.frombuffer(body[begin:end], dtype=dtype).reshape(shape).copy()
    return tensors, metadata


def write_safetensors(path, tensors, metadata):
    """Writes {name: array} (float32/uint32/int32/uint8) with string metadata.

    Tensors are stored by element size descending, then name (as the reference
    writer does), so that every tensor is aligned to its element size. The
    other tools of this folder write their fixtures with it too.
    """
    names = {v: k for k, v in DTYPES.items()}
    header, chunks, offset = {}, [], 0
    for name in sorted(tensors, key=lambda n: (-np.asarray(tensors[n]).dtype.itemsize, n)):
        arr = np.ascontiguousarray(tensors[name])
        arr = arr.astype(arr.dtype.newbyteorder("<"), copy=False)
        if arr.dtype not in names:
            raise ValueError(f"tensor {name!r}: unsupported dtype {arr.dtype}")
        raw = arr.tobytes()
        header[name] = {"dtype": names[arr.dtype], "shape": list(arr.shape),
                        "data_offsets": [offset, offset + len(raw)]}
        chunks.append(raw)
        offset += len(raw)
    header["__metadata__"] = {str(k): str(v) for k, v in metadata.items()}
    text = json.dumps(header, separators=(",", ":")).encode("utf-8")
    text += b" " * (-len(text) % 8)
    Path(path).write_bytes(struct.pack("<Q", len(text)) + text + b"".join(chunks))


# ----------------------------------------------------------------------- model

class LayerNorm2d(nn.Module):
    """Per-pixel LayerNorm over channels (biased variance, eps 1e-6)."""

    def __init__(self, c):
        super().__init__()
        self.weight = nn.Parameter(torch.ones(c))
        self.bias = nn.Parameter(torch.zeros(c))

    def forward(self, x):
        mu = x.mean(1, keepdim=True)
        var = (x - mu).pow(2).mean(1, keepdim=True)
        y = (x - mu) / torch.sqrt(var + 1e-6)
        return self.weight.view(1, -1, 1, 1) * y + self.bias.view(1, -1, 1, 1)


def simple_gate(z):
    """SimpleGate: the first half of the channels times the second half."""
    a, b = z.chunk(2, dim=1)
    return a * b


class NAFBlock(nn.Module):
    """NAFNet block: gated depthwise conv with channel attention, then a gated FFN."""

    def __init__(self, c):
        super().__init__()
        self.norm1 = LayerNorm2d(c)
        self.conv1 = nn.Conv2d(c, 2 * c, 1)
        self.conv2 = nn.Conv2d(2 * c, 2 * c, 3, padding=1, groups=2 * c)
        self.sca = nn.Conv2d(c, c, 1)
        self.conv3 = nn.Conv2d(c, c, 1)
        self.norm2 = LayerNorm2d(c)
        self.conv4 = nn.Conv2d(c, 2 * c, 1)
        self.conv5 = nn.Conv2d(c, c, 1)
        self.beta = nn.Parameter(torch.zeros(c))
        self.gamma = nn.Parameter(torch.zeros(c))

    def forward(self, x):
        t = simple_gate(self.conv2(self.conv1(self.norm1(x))))
        t = t * self.sca(F.adaptive_avg_pool2d(t, 1))
        y = x + self.conv3(t) * self.beta.view(1, -1, 1, 1)
        t = self.conv5(simple_gate(self.conv4(self.norm2(y))))
        return y + t * self.gamma.view(1, -1, 1, 1)


class Restorer(nn.Module):
    """NAFNet U-Net over T stacked frames, predicting the reference frame as a residual."""

    def __init__(self, frames, width, enc_blocks, middle_blocks, dec_blocks):
        super().__init__()
        if len(enc_blocks) != len(dec_blocks):
            raise CliError(f"enc_blocks {enc_blocks} and dec_blocks {dec_blocks} differ in length")
        self.frames, self.levels = frames, len(enc_blocks)
        self.intro = nn.Conv2d(3 * frames, width, 3, padding=1)
        self.encoders, self.downs = nn.ModuleList(), nn.ModuleList()
        self.ups, self.decoders = nn.ModuleList(), nn.ModuleList()
        c = width
        for n in enc_blocks:
            self.encoders.append(nn.Sequential(*[NAFBlock(c) for _ in range(n)]))
            self.downs.append(nn.Conv2d(c, 2 * c, 2, stride=2))
            c *= 2
        self.middle = nn.Sequential(*[NAFBlock(c) for _ in range(middle_blocks)])
        for n in dec_blocks:
            self.ups.append(nn.Conv2d(c, 2 * c, 1, bias=False))
            c //= 2
            self.decoders.append(nn.Sequential(*[NAFBlock(c) for _ in range(n)]))
        self.ending = nn.Conv2d(width, 3, 3, padding=1)

    def forward(self, inp):
        x = self.intro(inp)
        skips = []
        for encoder, down in zip(self.encoders, self.downs):
            x = encoder(x)
            skips.append(x)
            x = down(x)
        x = self.middle(x)
        for up, decoder, skip in zip(self.ups, self.decoders, reversed(skips)):
            x = decoder(F.pixel_shuffle(up(x), 2) + skip)
        r = self.frames // 2
        return self.ending(x) + inp[:, 3 * r:3 * r + 3]


def config_metadata(frames, width, enc_blocks, middle_blocks, dec_blocks):
    """The restorer metadata strings for a configuration."""
    return {"format": FORMAT, "network": NETWORK, "frames": str(frames), "width": str(width),
            "enc_blocks": ",".join(map(str, enc_blocks)), "middle_blocks": str(middle_blocks),
            "dec_blocks": ",".join(map(str, dec_blocks))}


def parse_ints(text, what):
    """Parses "1,2,3" into [1, 2, 3]; raises CliError naming `what` otherwise."""
    try:
        values = [int(v) for v in text.split(",")]
    except ValueError:
        raise CliError(f"{what} is {text!r}, not comma-separated integers like \"1,1,1\"") from None
    if not values or min(values) < 0:
        raise CliError(f"{what} is {text!r}; give one block count >= 0 per level")
    return values


def load_restorer(path):
    """Builds a Restorer from a restorer or checkpoint file's metadata and loads its weights."""
    tensors, meta = read_safetensors(path)
    if meta.get("format", FORMAT) != FORMAT or meta.get("network", NETWORK) != NETWORK:
        raise CliError(f"{path}: metadata format {meta.get('format')!r}, network "
                       f"{meta.get('network')!r}, not {FORMAT!r} and {NETWORK!r}; "
                       "pass a restorer file written by vkjr2")
    missing = [k for k in ("frames", "width", "enc_blocks", "middle_blocks", "dec_blocks")
               if k not in meta]
    if missing:
        raise CliError(f"{path}: metadata lacks {', '.join(missing)}; a restorer file must "
                       "carry its config (frames, width, enc_blocks, middle_blocks, dec_blocks)")
    try:
        frames, width, middle = int(meta["frames"]), int(meta["width"]), int(meta["middle_blocks"])
    except ValueError as e:
        raise CliError(f"{path}: bad metadata ({e}); frames/width/middle_blocks are integers") from e
    model = Restorer(frames, width, parse_ints(meta["enc_blocks"], f"{path}: enc_blocks"),
                     middle, parse_ints(meta["dec_blocks"], f"{path}: dec_blocks"))
    state = {}
    for name, param in model.state_dict().items():
        value = tensors.get(name, tensors.get("model." + name))
        if value is None:
            raise CliError(f"{path}: tensor {name!r} (or 'model.{name}') is missing; "
                           "the file does not match its metadata config")
        if list(value.shape) != list(param.shape) or value.dtype != np.float32:
            raise CliError(f"{path}: tensor {name!r} is {value.dtype} {list(value.shape)}, "
                           f"expected float32 {list(param.shape)}")
        state[name] = torch.from_numpy(value)
    model.load_state_dict(state)
    return model


def charbonnier(out, target, eps=CHARBONNIER_EPS):
    """Charbonnier loss: mean(sqrt((out - target)^2 + eps^2))."""
    return torch.sqrt((out - target) ** 2 + eps * eps).mean()


def to_f32(t):
    """A tensor as a float32 numpy array."""
    return t.detach().to(torch.float32).cpu().numpy()


# -------------------------------------------------------------------- commands

def cmd_fixture(args):
    """Writes the C++ parity fixture (float64 reference, stored as float32)."""
    cfg = dict(frames=2, width=4, enc_blocks=[1, 1], middle_blocks=1, dec_blocks=[1, 1])
    torch.manual_seed(args.seed)
    model = Restorer(**cfg)
    with torch.no_grad():
        for name, p in model.named_parameters():
            lo = 0.5 if ".norm" in name and name.endswith(".weight") else -0.5
            p.uniform_(lo, lo + 1.0)
    inp = torch.rand(2, 3 * cfg["frames"], 8, 8)
    r = cfg["frames"] // 2
    target = inp[:, 3 * r:3 * r + 3] + 0.05 * (2 * torch.rand(2, 3, 8, 8) - 1)
    tensors = {"model." + n: to_f32(p) for n, p in model.named_parameters()}
    tensors.update(input=to_f32(inp), target=to_f32(target))

    with torch.no_grad():
        out32 = model(inp)
    model64 = copy.deepcopy(model).double()
    out64 = model64(inp.double())
    loss = charbonnier(out64, target.double())
    loss.backward()
    tensors.update(output=to_f32(out64), output_f32=to_f32(out32), loss=to_f32(loss.reshape(1)))
    tensors.update({"grad." + n: to_f32(p.grad) for n, p in model64.named_parameters()})
    torch.optim.Adam(model64.parameters(), lr=ADAM_LR, betas=(0.9, 0.999), eps=1e-8,
                     weight_decay=0).step()
    tensors.update({"adam." + n: to_f32(p) for n, p in model64.named_parameters()})

    meta = config_metadata(**cfg)
    meta.update({"loss": "charbonnier", "charbonnier_eps": "0.001", "adam_lr": "0.001",
                 "seed": str(args.seed), "generator": "tools/restorer_torch.py fixture"})
    write_safetensors(args.out, tensors, meta)
    ref = out64.detach()
    diff = (out32.double() - ref).abs()
    rel = diff.max().item() / ref.abs().max().item()
    rel_elem = (diff / ref.abs().clamp_min(1e-6)).max().item()
    n_params = sum(p.numel() for p in model.parameters())
    print(f"wrote {args.out}: {Path(args.out).stat().st_size} bytes, {n_params} parameters, "
          f"loss {loss.item():.9g}\noutput float32 vs float64: max relative difference "
          f"{rel:.3g} (max |diff| / max |output|), elementwise {rel_elem:.3g}")


def cmd_run(args):
    """Runs a restorer in float32 on IN's "input" and writes "output"."""
    model = load_restorer(args.weights)
    tensors, _ = read_safetensors(args.inp)
    if "input" not in tensors:
        raise CliError(f"{args.inp}: no tensor 'input'; store the frames as 'input' [N,3T,H,W]")
    inp = torch.from_numpy(tensors["input"].astype(np.float32))
    levels = 2 ** model.levels
    if inp.ndim != 4 or inp.shape[1] != 3 * model.frames or inp.shape[2] % levels \
            or inp.shape[3] % levels:
        raise CliError(f"{args.inp}: 'input' is {list(inp.shape)}; expected [N, "
                       f"{3 * model.frames}, H, W] with H and W multiples of {levels}")
    with torch.no_grad():
        out = model(inp)
    write_safetensors(args.out, {"output": to_f32(out)}, {"generator": "tools/restorer_torch.py run"})
    print(f"wrote {args.out}: output {list(out.shape)}")


def timed(fn, repeat):
    """Runs fn once to warm up, then `repeat` times; returns the median seconds."""
    fn()
    times = []
    for _ in range(repeat):
        start = time.perf_counter()
        fn()
        times.append(time.perf_counter() - start)
    return statistics.median(times)


def cmd_bench(args):
    """Times CPU inference and one training step; prints JSON."""
    enc, dec = parse_ints(args.enc, "--enc"), parse_ints(args.dec, "--dec")
    if args.size % 2 ** len(enc):
        raise CliError(f"--size {args.size} is not a multiple of {2 ** len(enc)} (2^levels)")
    torch.set_num_threads(args.threads)
    torch.manual_seed(0)
    model = Restorer(args.frames, args.width, enc, args.middle, dec)
    inp = torch.rand(args.batch, 3 * args.frames, args.size, args.size)
    target = torch.rand(args.batch, 3, args.size, args.size)
    optim = torch.optim.Adam(model.parameters(), lr=ADAM_LR)

    def infer():
        with torch.no_grad():
            model(inp)

    def train_step():
        optim.zero_grad()
        charbonnier(model(inp), target).backward()
        optim.step()

    result = {"infer_s": timed(infer, args.repeat), "train_step_s": timed(train_step, args.repeat),
              "params": sum(p.numel() for p in model.parameters()),
              "frames": args.frames, "width": args.width, "enc_blocks": enc,
              "middle_blocks": args.middle, "dec_blocks": dec, "size": args.size,
              "batch": args.batch, "threads": args.threads, "repeat": args.repeat,
              "torch": torch.__version__}
    print(json.dumps(result))


def build_parser():
    """The argparse parser with the fixture, run and bench subcommands."""
    parser = argparse.ArgumentParser(description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    sub = parser.add_subparsers(dest="command", required=True)
    p = sub.add_parser("fixture", help="write the C++ parity fixture")
    p.add_argument("out", help="output .safetensors path")
    p.add_argument("--seed", type=int, default=5, help="torch.manual_seed (default 5)")
    p.set_defaults(func=cmd_fixture)
    p = sub.add_parser("run", help="run a restorer on IN's 'input' tensor")
    p.add_argument("weights", help="restorer or checkpoint .safetensors (config in metadata)")
    p.add_argument("inp", metavar="in", help=".safetensors with tensor 'input' [N,3T,H,W]")
    p.add_argument("out", help="output .safetensors (tensor 'output' [N,3,H,W])")
    p.set_defaults(func=cmd_run)
    p = sub.add_parser("bench", help="time CPU inference and a training step, print JSON")
    p.add_argument("--frames", type=int, default=8, help="input frames T (default 8)")
    p.add_argument("--width", type=int, default=16, help="base width w (default 16)")
    p.add_argument("--enc", default="1,1,1", help="encoder blocks per level (default 1,1,1)")
    p.add_argument("--middle", type=int, default=1, help="middle blocks (default 1)")
    p.add_argument("--dec", default="1,1,1",
                   help="decoder blocks per level, deepest first (default 1,1,1)")
    p.add_argument("--size", type=int, default=160, help="square image side (default 160)")
    p.add_argument("--batch", type=int, default=1, help="batch size N (default 1)")
    p.add_argument("--threads", type=int, default=2, help="torch.set_num_threads (default 2)")
    p.add_argument("--repeat", type=int, default=5,
                   help="timed runs after one warm-up; the median is reported (default 5)")
    p.set_defaults(func=cmd_bench)
    return parser


def run_main(parser, argv=None):
    """Parses arguments, runs the command, reports CliError as 'error: ...' (exit 2).

    The entry point of every tool of this folder."""
    args = parser.parse_args(argv)
    try:
        args.func(args)
    except CliError as e:
        print(f"error: {e}", file=sys.stderr)
        return 2
    return 0


def main(argv=None):
    """Entry point."""
    return run_main(build_parser(), argv)


if __name__ == "__main__":
    sys.exit(main())
