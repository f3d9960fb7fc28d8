#!/usr/bin/env node
// The TF.js peer of vkjr2's face-model benchmarks: face-api 1.7.15 on TF.js
// 4.22 (WASM backend, SIMD, 1 thread) timing, per face, the recognition net
// (150x150 input), the landmark net (one face crop) and the tiny face detector
// at 416 on sample1; and a batch of 8 faces through the recognition and the
// landmark nets (net only: inputs already at the net's size, as face-api's
// forward() takes an array of them). Median over --runs runs after --warmup
// warm-ups.
//
//   node bench/faceapi_bench.mjs [--json out.json] [--runs 10] [--warmup 2]
//        [--backend wasm|cpu] [--node-modules DIR] [--models DIR] [--images DIR]
//        [--frames DIR] [--serve]
//
// --frames DIR (bench/pipeline_bench): DIR/index.json lists probes, each a
// list of sampled frames as raw 8-bit RGB files ({"input_size": S, "probes":
// [{"name": N, "frames": [{"file", "width", "height"}]}]}); benchmark N runs
// face-api's detectAllFaces(frame, TinyFaceDetectorOptions(S, 0.5))
// .withFaceLandmarks().withFaceDescriptors() on each of its frames (the
// frames are tensors before the timing starts, as a decoded video's are).
//
// --serve: for bench/nets_bench, which interleaves these runs with its own so
// that both see the same machine load. After the warm-ups it prints one JSON
// line {"ready": true, "peer", "backend", ...}, then answers each line NAME
// read from stdin (a benchmark name below) with one timed run,
// {"name": NAME, "ms": T}, or {"error": "..."}; "quit" or end of input ends it.
//
// node_modules are found as tests/parity/face_api_reference.mjs finds them
// (see tests/parity/README.md): normally the install scripts/setup made in
// $VKJR2_CACHE_DIR/node-parity-<lock hash>/, nothing to pass.
import fs from 'node:fs';
import readline from 'node:readline';
import os from 'node:os';
import path from 'node:path';
import { decodeJpeg, loadFaceApi } from '../tests/parity/face_api_reference.mjs';

const USAGE = `usage: node bench/faceapi_bench.mjs [--json out.json] [--runs 10] [--warmup 2]
       [--backend wasm|cpu] [--node-modules DIR] [--models DIR] [--images DIR] [--frames DIR] [--serve]`;

const BATCH = 8;  // as kBatch in bench/nets_bench.cpp

function parseArgs(argv) {
  const args = { runs: 10, warmup: 2, backend: 'wasm' };
  for (let i = 0; i < argv.length; i++) {
    const a = argv[i];
    const val = () => {
      if (i + 1 >= argv.length) throw new Error(`${a} needs a value`);
      return argv[++i];
    };
    const count = (min) => {
      const v = val();
      const n = Number(v);
      if (!Number.isInteger(n) || n < min) throw new Error(`${a} ${v}: expected an integer >= ${min}`);
      return n;
    };
    if (a === '--json') args.json = val();
    else if (a === '--runs') args.runs = count(1);
    else if (a === '--warmup') args.warmup = count(0);
    else if (a === '--backend') args.backend = val();
    else if (a === '--node-modules') args.nodeModules = val();
    else if (a === '--models') args.models = val();
    else if (a === '--images') args.images = val();
    else if (a === '--serve') args.serve = true;
    else if (a === '--frames') args.frames = val();
    else if (a === '-h' || a === '--help') args.help = true;
    else throw new Error(`unknown argument ${a}\n${USAGE}`);
  }
  return args;
}

async function time(fn, runs, warmup) {
  for (let i = 0; i < warmup; i++) await fn();
  const ms = [];
  for (let i = 0; i < runs; i++) {
    const t0 = performance.now();
    await fn();
    ms.push(performance.now() - t0);
  }
  ms.sort((a, b) => a - b);
  const mid = Math.floor(ms.length / 2);
  const median = ms.length % 2 ? ms[mid] : (ms[mid - 1] + ms[mid]) / 2;
  return { median, min: ms[0], max: ms[ms.length - 1] };
}

// --serve: one timed run per request line (see the header).
async function serve(benches, warmup, about) {
  for (const b of benches) for (let i = 0; i < warmup; i++) await b.fn();
  console.log(JSON.stringify({ ready: true, ...about, benchmarks: benches.map((b) => b.name) }));
  const byName = new Map(benches.map((b) => [b.name, b]));
  for await (const line of readline.createInterface({ input: process.stdin, terminal: false })) {
    const name = line.trim();
    if (name === 'quit') break;
    if (name === '') continue;
    const b = byName.get(name);
    if (!b) {
      console.log(JSON.stringify({ error: `unknown benchmark ${name}` }));
      continue;
    }
    const t0 = performance.now();
    await b.fn();
    console.log(JSON.stringify({ name, ms: performance.now() - t0 }));
  }
}

function writeJsonAtomic(file, value) {
  const tmp = `${file}.tmp-${process.pid}`;
  fs.writeFileSync(tmp, `${JSON.stringify(value, null, 2)}\n`);
  fs.renameSync(tmp, file);
}

async function main() {
  const args = parseArgs(process.argv.slice(2));
  if (args.help) {
    console.log(USAGE);
    return;
  }
  const { tf, faceapi, jpeg, info } = await loadFaceApi({
    nodeModules: args.nodeModules, backend: args.backend, modelsDir: args.models,
  });
  const imagesDir = args.images || path.join(info.node_modules, '@vladmandic', 'face-api', 'demo');
  const { width, height, rgb } = decodeJpeg(jpeg, path.join(imagesDir, 'sample1.jpg'));
  const image = tf.tensor3d(rgb, [height, width, 3], 'float32');
  const options = new faceapi.TinyFaceDetectorOptions({ inputSize: 416, scoreThreshold: 0.5 });

  // One face's inputs, made exactly as face-api's pipeline makes them.
  const faces = await faceapi.detectAllFaces(image, options).withFaceLandmarks();
  if (!faces.length) throw new Error('face-api found no face in sample1.jpg; the bench needs one');
  const [lmCrop] = await faceapi.extractFaceTensors(image, [faces[0].detection]);
  const [chip] = await faceapi.extractFaceTensors(image, [faces[0].landmarks.align(null, { useDlibAlignment: true })]);
  const chip150 = tf.tidy(() => new faceapi.NetInput([chip]).toBatchTensor(150, true).squeeze([0]));
  const lm112 = tf.tidy(() => new faceapi.NetInput([lmCrop]).toBatchTensor(112, true).squeeze([0]));
  // A batch of 8 faces, net only: face-api's forward() on an array of inputs
  // already at the net's size (no resize), outputs read back.
  const batch = async (net, input) => {
    const out = await net.forward(Array(BATCH).fill(input));
    await out.data();
    out.dispose();
  };

  const benches = [
    {
      name: 'faceapi_recognition_150',
      what: 'FaceRecognitionNet, one 150x150 face, descriptor read back',
      fn: () => faceapi.nets.faceRecognitionNet.computeFaceDescriptor(chip150),
    },
    {
      name: 'faceapi_landmarks_112',
      what: `FaceLandmark68Net, one ${lmCrop.shape[1]}x${lmCrop.shape[0]} face crop (pad + resize to 112 included)`,
      fn: () => faceapi.nets.faceLandmark68Net.detectLandmarks(lmCrop),
    },
    {
      name: 'faceapi_recognition_150_batch8',
      faces: BATCH,
      what: `FaceRecognitionNet, batch of ${BATCH} 150x150 faces (net only), outputs read back`,
      fn: () => batch(faceapi.nets.faceRecognitionNet, chip150),
    },
    {
      name: 'faceapi_landmarks_112_batch8',
      faces: BATCH,
      what: `FaceLandmark68Net, batch of ${BATCH} 112x112 faces (net only), outputs read back`,
      fn: () => batch(faceapi.nets.faceLandmark68Net, lm112),
    },
    {
      name: 'faceapi_tiny_detector_416',
      what: `TinyFaceDetector, sample1 ${width}x${height} at 416 (pad + resize + decode + NMS included)`,
      fn: () => faceapi.nets.tinyFaceDetector.locateFaces(image, options),
    },
  ];

  // Probe videos' sampled frames (--frames): face-api's whole pipeline per frame.
  const frameTensors = [];
  if (args.frames) {
    const index = JSON.parse(fs.readFileSync(path.join(args.frames, 'index.json'), 'utf8'));
    const probeOptions = new faceapi.TinyFaceDetectorOptions({ inputSize: index.input_size, scoreThreshold: 0.5 });
    for (const probe of index.probes) {
      const frames = probe.frames.map((f) => {
        const bytes = fs.readFileSync(path.join(args.frames, f.file));
        if (bytes.length !== f.width * f.height * 3) throw new Error(`${f.file}: expected ${f.width}x${f.height}x3 bytes`);
        return tf.tensor3d(new Float32Array(bytes), [f.height, f.width, 3], 'float32');
      });
      frameTensors.push(...frames);
      benches.push({
        name: probe.name,
        faces: frames.length,
        what: `face-api detect (${index.input_size}) + landmarks + descriptors on ${frames.length} frames`,
        fn: async () => {
          for (const frame of frames) {
            await faceapi.detectAllFaces(frame, probeOptions).withFaceLandmarks().withFaceDescriptors();
          }
        },
      });
    }
  }

  const peer = `face-api ${info.versions.face_api} / TF.js ${info.versions.tfjs} ${info.backend}`
    + (info.backend === 'wasm' ? ` (SIMD ${info.wasm_simd ? 'on' : 'off'}, ${info.wasm_threads} thread)` : ' (pure JS)');
  const about = {
    peer,
    backend: info.backend,
    wasm_simd: info.wasm_simd ?? null,
    wasm_threads: info.wasm_threads ?? null,
    node: process.version,
    machine: `${os.cpus()[0]?.model ?? 'unknown CPU'} (${os.cpus().length} logical CPUs)`,
  };
  if (args.serve) {
    await serve(benches, args.warmup, about);
    tf.dispose([image, lmCrop, chip, chip150, lm112, ...frameTensors]);
    return;
  }
  console.log(`${peer}, median of ${args.runs} runs after ${args.warmup} warm-ups`);
  console.log(`${'benchmark'.padEnd(30)} ${'median ms'.padStart(10)} ${'min ms'.padStart(9)} ${'max ms'.padStart(9)} `
    + `${'faces/s'.padStart(8)}  what`);
  const results = [];
  for (const b of benches) {
    const t = await time(b.fn, args.runs, args.warmup);
    results.push({
      name: b.name,
      value: t.median,
      unit: 'ms',
      min_ms: t.min,
      max_ms: t.max,
      runs: args.runs,
      warmup: args.warmup,
      what: b.what,
    });
    const facesPerRun = b.faces ?? 1;
    console.log(`${b.name.padEnd(30)} ${t.median.toFixed(2).padStart(10)} ${t.min.toFixed(2).padStart(9)} `
      + `${t.max.toFixed(2).padStart(9)} ${((1000 * facesPerRun) / t.median).toFixed(1).padStart(8)}  ${b.what}`);
  }
  tf.dispose([image, lmCrop, chip, chip150, lm112, ...frameTensors]);

  if (args.json) {
    writeJsonAtomic(args.json, { ...about, results });
    console.log(`wrote ${args.json}`);
  }
}

main().catch((e) => {
  console.error(`faceapi_bench: error: ${e.message}`);
  process.exit(1);
});
