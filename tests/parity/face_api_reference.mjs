#!/usr/bin/env node
// Numerical oracle for vkjr2's face models: runs the real face-api
// (@vladmandic/face-api 1.7.15 on TF.js 4.22) on the package's sample photos
// and writes the reference directory that the C++ parity tests read. The
// layout is documented in tests/parity/README.md; keep the two in step.
//
//   node tests/parity/face_api_reference.mjs --out DIR [--backend wasm|cpu]
//        [--models DIR] [--images DIR] [--only sample1,sample3]
//        [--node-modules DIR] [--force]
//
// The output directory is written under a temporary name and renamed when
// complete, so a reader never sees a half-written reference set.
//
// This file also exports the helpers bench/faceapi_bench.mjs uses (finding
// node_modules, starting a backend, decoding a JPEG), so both find the same
// installation the same way.
import { createHash } from 'node:crypto';
import fs from 'node:fs';
import { createRequire } from 'node:module';
import os from 'node:os';
import path from 'node:path';
import { fileURLToPath, pathToFileURL } from 'node:url';

const HERE = path.dirname(fileURLToPath(import.meta.url));
export const FACE_API_VERSION = '1.7.15';
export const TFJS_VERSION = '4.22.0';
const DETECTOR_INPUT_SIZE = 416;
const DETECTOR_SCORE_THRESHOLD = 0.5;

export function cacheDir() {
  return process.env.VKJR2_CACHE_DIR || path.join(os.homedir(), '.cache', 'vkjr2');
}

// The key scripts/setup uses for the npm install: first 16 hex digits of the
// sha256 of tests/parity/package-lock.json.
export function lockKey() {
  const lock = fs.readFileSync(path.join(HERE, 'package-lock.json'));
  return createHash('sha256').update(lock).digest('hex').slice(0, 16);
}

// node_modules holding face-api and TF.js, in this order: --node-modules,
// $VKJR2_PARITY_NODE_MODULES, tests/parity/node_modules (a local `npm ci`),
// $VKJR2_CACHE_DIR/node-parity-<lockKey>/node_modules (what setup installs).
export function findNodeModules(explicit) {
  const candidates = [];
  if (explicit) candidates.push(['--node-modules', explicit]);
  if (process.env.VKJR2_PARITY_NODE_MODULES) {
    candidates.push(['$VKJR2_PARITY_NODE_MODULES', process.env.VKJR2_PARITY_NODE_MODULES]);
  }
  candidates.push(['tests/parity/node_modules', path.join(HERE, 'node_modules')]);
  candidates.push(['setup cache', path.join(cacheDir(), `node-parity-${lockKey()}`, 'node_modules')]);
  for (const [, dir] of candidates) {
    if (fs.existsSync(path.join(dir, '@vladmandic', 'face-api', 'package.json'))) return path.resolve(dir);
  }
  const tried = candidates.map(([what, dir]) => `  ${what}: ${dir}`).join('\n');
  throw new Error(`face-api is not installed; looked for node_modules/@vladmandic/face-api in\n${tried}\n`
    + 'Fix: run scripts/setup (it runs `npm ci` for tests/parity into the cache), '
    + 'or pass --node-modules DIR.');
}

// Loads TF.js, its WASM backend, face-api and jpeg-js from one node_modules,
// selects the backend and loads the three face models.
export async function loadFaceApi({ nodeModules, backend = 'wasm', modelsDir } = {}) {
  if (backend !== 'wasm' && backend !== 'cpu') {
    throw new Error(`--backend ${backend}: unknown backend; use wasm or cpu`);
  }
  const nm = findNodeModules(nodeModules);
  const req = createRequire(path.join(nm, 'noop.js'));
  const tf = req('@tensorflow/tfjs');
  const wasm = req('@tensorflow/tfjs-backend-wasm');
  const faceapi = req('@vladmandic/face-api/dist/face-api.node-wasm.js');
  const jpeg = req('jpeg-js');
  const versions = {
    face_api: req('@vladmandic/face-api/package.json').version,
    tfjs: req('@tensorflow/tfjs/package.json').version,
    tfjs_backend_wasm: req('@tensorflow/tfjs-backend-wasm/package.json').version,
    jpeg_js: req('jpeg-js/package.json').version,
  };
  if (versions.face_api !== FACE_API_VERSION || versions.tfjs !== TFJS_VERSION) {
    throw new Error(`${nm} holds face-api ${versions.face_api} / TF.js ${versions.tfjs}; `
      + `expected ${FACE_API_VERSION} / ${TFJS_VERSION}. Fix: run scripts/setup again.`);
  }
  if (backend === 'wasm') wasm.setThreadsCount(1); // Node has no wasm threads anyway; make it explicit
  if (!(await tf.setBackend(backend))) throw new Error(`TF.js could not start the ${backend} backend`);
  await tf.ready();
  const info = { backend: tf.getBackend(), versions, node_modules: nm };
  if (backend === 'wasm') {
    info.wasm_threads = wasm.getThreadsCount();
    info.wasm_simd = await tf.env().getAsync('WASM_HAS_SIMD_SUPPORT');
  }
  const models = modelsDir || path.join(nm, '@vladmandic', 'face-api', 'model');
  const manifests = ['tiny_face_detector_model', 'face_landmark_68_model', 'face_recognition_model'];
  for (const f of manifests.map((m) => `${m}-weights_manifest.json`)) {
    if (!fs.existsSync(path.join(models, f))) {
      throw new Error(`model manifest ${path.join(models, f)} is missing. Fix: pass --models DIR `
        + "pointing at face-api's model/ folder (scripts/setup unpacks it to $VKJR2_CACHE_DIR/face-api-1.7.15/model).");
    }
  }
  await faceapi.nets.tinyFaceDetector.loadFromDisk(models);
  await faceapi.nets.faceLandmark68Net.loadFromDisk(models);
  await faceapi.nets.faceRecognitionNet.loadFromDisk(models);
  info.models = path.resolve(models);
  return { tf, faceapi, jpeg, info };
}

// Decodes a JPEG with jpeg-js into a float32 HWC RGB array (0..255).
export function decodeJpeg(jpeg, file) {
  let img;
  try {
    img = jpeg.decode(fs.readFileSync(file), { useTArray: true, formatAsRGBA: false });
  } catch (e) {
    throw new Error(`${file}: cannot decode as JPEG (${e.message}); pass a valid .jpg`);
  }
  const { width, height, data } = img;
  if (data.length !== width * height * 3) {
    throw new Error(`${file}: decoder returned ${data.length} bytes for ${width}x${height} RGB`);
  }
  return { width, height, rgb: Float32Array.from(data) };
}

// ---- .npy v1.0 writer ('<f4', C order) ------------------------------------
function npyBytes(shape, values) {
  const count = shape.reduce((a, b) => a * b, 1);
  if (values.length !== count) throw new Error(`npy: ${values.length} values for shape ${shape}`);
  const dims = shape.length === 1 ? `${shape[0]},` : shape.join(', ');
  let header = `{'descr': '<f4', 'fortran_order': False, 'shape': (${dims}), }`;
  // magic (6) + version (2) + header length (2) + header + '\n', padded to 64.
  const pad = 64 - ((10 + header.length + 1) % 64);
  header += ' '.repeat(pad % 64) + '\n';
  const buf = Buffer.alloc(10 + header.length + 4 * count);
  buf.write('\x93NUMPY', 0, 'latin1');
  buf[6] = 1;
  buf[7] = 0;
  buf.writeUInt16LE(header.length, 8);
  buf.write(header, 10, 'latin1');
  let o = 10 + header.length;
  for (let i = 0; i < count; i++, o += 4) buf.writeFloatLE(values[i], o);
  return buf;
}

async function writeTensorNpy(dir, name, tensor) {
  const shape = tensor.shape[0] === 1 && tensor.shape.length === 4 ? tensor.shape.slice(1) : tensor.shape;
  fs.writeFileSync(path.join(dir, name), npyBytes(shape, await tensor.data()));
  return name;
}

// ---- JSON with arrays of numbers on one line ---------------------------------
function toJson(value, indent = '') {
  const next = `${indent}  `;
  if (Array.isArray(value)) {
    if (value.every((v) => typeof v === 'number' || (Array.isArray(v) && v.every((w) => typeof w === 'number')))) {
      return JSON.stringify(value);
    }
    if (value.length === 0) return '[]';
    return `[\n${value.map((v) => next + toJson(v, next)).join(',\n')}\n${indent}]`;
  }
  if (value && typeof value === 'object') {
    const keys = Object.keys(value);
    if (keys.length === 0) return '{}';
    if (keys.every((k) => typeof value[k] === 'number')) return JSON.stringify(value);
    return `{\n${keys.map((k) => `${next}${JSON.stringify(k)}: ${toJson(value[k], next)}`).join(',\n')}\n${indent}}`;
  }
  if (typeof value === 'number' && !Number.isFinite(value)) throw new Error(`non-finite number ${value} in output`);
  return JSON.stringify(value); // shortest round-trip form: exact for every float32/float64 value
}

const rectOf = (b) => ({ x: b.x, y: b.y, width: b.width, height: b.height });
const maxAbsDiff = (a, b) => a.reduce((m, v, i) => Math.max(m, Math.abs(v - b[i])), 0);

// ---- the reference run --------------------------------------------------------
async function detectorRaw(tf, faceapi, imageTensor, dir, name) {
  // Same steps as TinyYolov2Base.detect(), with the intermediate values kept.
  const net = faceapi.nets.tinyFaceDetector;
  const netInput = await faceapi.toNetInput(imageTensor);
  const input416 = netInput.toBatchTensor(DETECTOR_INPUT_SIZE, false);
  const out = net.forwardInput(netInput, DETECTOR_INPUT_SIZE);
  const reshaped = netInput.getReshapedInputDimensions(0);
  const imgW = netInput.getInputWidth(0);
  const imgH = netInput.getInputHeight(0);
  const candidates = await net.extractBoxes(out, reshaped, DETECTOR_SCORE_THRESHOLD);
  const kept = faceapi.nonMaxSuppression(
    candidates.map((c) => c.box.rescale(DETECTOR_INPUT_SIZE)),
    candidates.map((c) => c.score),
    net.config.iouThreshold,
    true,
  );
  const entry = (c) => ({
    row: c.row,
    col: c.col,
    anchor: c.anchor,
    score: c.score,
    box_relative: rectOf(c.box),
    box: rectOf(c.box.rescale({ width: imgW, height: imgH })),
  });
  const raw = {
    input_size: DETECTOR_INPUT_SIZE,
    score_threshold: DETECTOR_SCORE_THRESHOLD,
    iou_threshold: net.config.iouThreshold,
    reshaped_width: reshaped.width,
    reshaped_height: reshaped.height,
    input: await writeTensorNpy(dir, `${name}_det_in.npy`, input416),
    output: await writeTensorNpy(dir, `${name}_det_out.npy`, out),
    before_nms: candidates.map(entry),
    kept,
    after_nms: kept.map((i) => entry(candidates[i])),
  };
  tf.dispose([input416, out]);
  return raw;
}

async function faceReference(tf, faceapi, imageTensor, result, dir, stem) {
  const { detection, landmarks } = result;
  const [imgH, imgW] = imageTensor.shape;
  // Landmark net input: the detection box cropped as extractFaceTensors does.
  const lmBox = detection.forSize(imgW, imgH).box.clipAtImageBorders(imgW, imgH);
  const [lmCrop] = await faceapi.extractFaceTensors(imageTensor, [detection]);
  const lmNet = faceapi.nets.faceLandmark68Net;
  const lmInput = await faceapi.toNetInput(lmCrop);
  const lmRaw = lmNet.runNet(lmInput); // sets lmInput.inputSize = 112
  const lm112 = lmInput.toBatchTensor(112, true);
  const lmRel = lmNet.postProcess(lmRaw, 112, [{ width: lmCrop.shape[1], height: lmCrop.shape[0] }]);
  const rawValues = Array.from(await lmRaw.data());
  const relValues = Array.from(await lmRel.data());
  // FaceLandmarks: relative * crop size + the (unfloored) detection box origin.
  const recomputed = [];
  for (let i = 0; i < 68; i++) {
    recomputed.push([
      relValues[2 * i] * lmCrop.shape[1] + detection.box.x,
      relValues[2 * i + 1] * lmCrop.shape[0] + detection.box.y,
    ]);
  }
  const positions = landmarks.positions.map((p) => [p.x, p.y]);
  const lmDiff = maxAbsDiff(positions.flat(), recomputed.flat());

  // Recognition input: the "dlib" alignment rect, cropped the same way.
  const chipRect = landmarks.align(null, { useDlibAlignment: true });
  const chipBox = chipRect.clipAtImageBorders(imgW, imgH);
  const [chip] = await faceapi.extractFaceTensors(imageTensor, [chipRect]);
  const chip150 = new faceapi.NetInput([chip]).toBatchTensor(150, true);
  const chip150_3d = chip150.squeeze([0]);
  const descriptor150 = Array.from(await faceapi.nets.faceRecognitionNet.computeFaceDescriptor(chip150_3d));
  const descriptor = Array.from(result.descriptor);

  const face = {
    score: detection.score,
    box: rectOf(detection.box),
    landmarks: positions,
    landmarks_box: rectOf(lmBox),
    landmarks_input: await writeTensorNpy(dir, `${stem}_lm_in.npy`, lmCrop),
    landmarks_112: await writeTensorNpy(dir, `${stem}_lm_112.npy`, lm112),
    landmarks_raw: rawValues,
    landmarks_relative: relValues,
    chip: await writeTensorNpy(dir, `${stem}_chip.npy`, chip),
    chip_rect: rectOf(chipRect),
    chip_box: rectOf(chipBox),
    recognition_150: await writeTensorNpy(dir, `${stem}_150.npy`, chip150_3d),
    descriptor,
    descriptor_150: descriptor150,
    checks: {
      landmarks_recomputed_max_abs_diff: lmDiff,
      descriptor_150_max_abs_diff: maxAbsDiff(descriptor, descriptor150),
    },
  };
  tf.dispose([lmCrop, lmRaw, lm112, lmRel, chip, chip150, chip150_3d]);
  if (lmDiff > 1e-3 || face.checks.descriptor_150_max_abs_diff > 1e-4) {
    throw new Error(`${stem}: the step-by-step recomputation disagrees with face-api's own pipeline `
      + `(landmarks ${lmDiff}, descriptor ${face.checks.descriptor_150_max_abs_diff}); `
      + 'this script no longer mirrors face-api and must be fixed');
  }
  return face;
}

function parseArgs(argv) {
  const args = { backend: 'wasm', force: false };
  for (let i = 0; i < argv.length; i++) {
    const a = argv[i];
    const val = () => {
      if (i + 1 >= argv.length) throw new Error(`${a} needs a value`);
      return argv[++i];
    };
    if (a === '--out') args.out = val();
    else if (a === '--backend') args.backend = val();
    else if (a === '--models') args.models = val();
    else if (a === '--images') args.images = val();
    else if (a === '--only') args.only = val().split(',').filter(Boolean);
    else if (a === '--node-modules') args.nodeModules = val();
    else if (a === '--force') args.force = true;
    else if (a === '-h' || a === '--help') args.help = true;
    else throw new Error(`unknown argument ${a}; see --help`);
  }
  return args;
}

const USAGE = `usage: node tests/parity/face_api_reference.mjs --out DIR [--backend wasm|cpu]
       [--models DIR] [--images DIR] [--only sample1,...] [--node-modules DIR] [--force]
Writes face-api reference outputs (layout: tests/parity/README.md) to DIR.
  --backend       TF.js backend: wasm (default, SIMD, 1 thread) or cpu (pure JS, slow)
  --models        face-api model/ folder (default: the installed package's)
  --images        folder with sample1.jpg..sample6.jpg (default: the installed package's demo/)
  --only          comma-separated image names to run (default: every sample*.jpg)
  --node-modules  node_modules holding face-api (default: see README.md)
  --force         replace DIR if it exists`;

async function main() {
  const args = parseArgs(process.argv.slice(2));
  if (args.help) {
    console.log(USAGE);
    return;
  }
  if (!args.out) throw new Error(`--out DIR is required\n${USAGE}`);
  const out = path.resolve(args.out);
  if (fs.existsSync(out) && !args.force) {
    throw new Error(`${out} exists; pass --force to replace it or choose another --out`);
  }
  const t0 = performance.now();
  const { tf, faceapi, jpeg, info } = await loadFaceApi({
    nodeModules: args.nodeModules, backend: args.backend, modelsDir: args.models,
  });
  const imagesDir = path.resolve(args.images || path.join(info.node_modules, '@vladmandic', 'face-api', 'demo'));
  let names = fs.existsSync(imagesDir)
    ? fs.readdirSync(imagesDir).filter((f) => /^sample\d+\.jpg$/.test(f)).map((f) => f.slice(0, -4))
    : [];
  names.sort((a, b) => Number(a.slice(6)) - Number(b.slice(6)));
  if (args.only) {
    const missing = args.only.filter((n) => !names.includes(n));
    if (missing.length) throw new Error(`--only: no ${missing.join(', ')}.jpg in ${imagesDir}`);
    names = args.only;
  }
  if (!names.length) throw new Error(`no sample*.jpg in ${imagesDir}; pass --images DIR`);
  console.log(`face-api ${info.versions.face_api}, TF.js ${info.versions.tfjs}, backend ${info.backend}`
    + (info.backend === 'wasm' ? ` (simd ${info.wasm_simd}, threads ${info.wasm_threads})` : ''));

  fs.mkdirSync(path.dirname(out), { recursive: true });
  const tmp = fs.mkdtempSync(`${out}.tmp-`);
  fs.chmodSync(tmp, 0o755); // mkdtemp makes it 0700; the references are for every user
  try {
    const index = {
      face_api: info.versions.face_api,
      tfjs: info.versions.tfjs,
      backend: info.backend,
      jpeg_js: info.versions.jpeg_js,
      detector_options: { input_size: DETECTOR_INPUT_SIZE, score_threshold: DETECTOR_SCORE_THRESHOLD },
      images: [],
    };
    const options = new faceapi.TinyFaceDetectorOptions({
      inputSize: DETECTOR_INPUT_SIZE, scoreThreshold: DETECTOR_SCORE_THRESHOLD,
    });
    for (const name of names) {
      const t1 = performance.now();
      const { width, height, rgb } = decodeJpeg(jpeg, path.join(imagesDir, `${name}.jpg`));
      fs.writeFileSync(path.join(tmp, `${name}.npy`), npyBytes([height, width, 3], rgb));
      const image = tf.tensor3d(rgb, [height, width, 3], 'float32');
      const results = await faceapi.detectAllFaces(image, options).withFaceLandmarks().withFaceDescriptors();
      const entry = {
        name,
        pixels: `${name}.npy`,
        width,
        height,
        detector_raw: await detectorRaw(tf, faceapi, image, tmp, name),
        detections: [],
      };
      if (entry.detector_raw.after_nms.length !== results.length) {
        throw new Error(`${name}: face-api found ${results.length} faces, the raw detector replay `
          + `${entry.detector_raw.after_nms.length}; this script no longer mirrors face-api`);
      }
      for (let f = 0; f < results.length; f++) {
        entry.detections.push(await faceReference(tf, faceapi, image, results[f], tmp, `${name}_f${f}`));
      }
      tf.dispose(image);
      index.images.push(entry);
      console.log(`  ${name} ${width}x${height}: ${results.length} face(s), `
        + `${((performance.now() - t1) / 1000).toFixed(1)} s`);
    }
    fs.writeFileSync(path.join(tmp, 'index.json'), `${toJson(index)}\n`);
    if (fs.existsSync(out)) fs.rmSync(out, { recursive: true });
    fs.renameSync(tmp, out);
  } catch (e) {
    fs.rmSync(tmp, { recursive: true, force: true });
    throw e;
  }
  const faces = JSON.parse(fs.readFileSync(path.join(out, 'index.json'), 'utf8')).images
    .reduce((n, im) => n + im.detections.length, 0);
  console.log(`wrote ${faces} faces from ${names.length} images to ${out} in `
    + `${((performance.now() - t0) / 1000).toFixed(1)} s`);
}

if (import.meta.url === pathToFileURL(process.argv[1] || '').href) {
  main().catch((e) => {
    console.error(`face_api_reference: error: ${e.message}`);
    process.exit(1);
  });
}
