// Reads a probekit Bevy export with ktx-parse (an independent KTX 2.0 reader) and checks it
// against probekit's CPU sampler (tests/engines/bevy_test.sh drives it):
//   node bevy_ktx_parse.mjs points FILE.ktx2            CSV of every voxel centre x 6 axis normals
//   node bevy_ktx_parse.mjs check FILE.ktx2 SAMPLED.csv  container, then every texel
// SAMPLED.csv is `probekit sample`'s irradiance E at those points. The exporter's face values are
// the least-squares ambient cube of E / pi (exporters/include/probekit/exporters/bevy.hpp):
// face(a, +-) = max(0, (E(+a) + E(-a)) / 2 +- (5/4) (E(+a) - E(-a)) / 2) / pi, which is what
// the check expects at texel (x, y + (negative ? Ry : 0), z + a Rz), the layout of Bevy's
// irradiance_volume.wesl.
import { readFileSync } from 'node:fs';
import { createRequire } from 'node:module';
import { pathToFileURL } from 'node:url';

// ktx-parse is installed under integrations/ (npm ci --prefix integrations), which is not on
// this file's own module path: resolve it from there.
const fromIntegrations = createRequire(new URL('../../integrations/package.json', import.meta.url));
const { read, VK_FORMAT_R16G16B16A16_SFLOAT, KHR_DF_MODEL_RGBSDA, KHR_DF_TRANSFER_LINEAR,
        KHR_DF_PRIMARIES_BT709 } =
  await import(pathToFileURL(fromIntegrations.resolve('ktx-parse')).href);

// A binary16 value is the float rounded to nearest (2^-11 relative). The sampled E comes from
// positions printed to 9 digits (grid coordinates off by ~1e-6 of a cell) and float sums: 1e-4
// of the largest face bounds both, and is still far below any two faces' difference.
const HALF_RELATIVE = 1 / 2048;
const SAMPLING_RELATIVE = 1e-4;

function fail(message) {
  console.error(`bevy_ktx_parse: ${message}`);
  process.exit(1);
}

function halfToFloat(h) {
  const sign = h & 0x8000 ? -1 : 1;
  const exponent = (h >> 10) & 0x1f;
  const mantissa = h & 0x3ff;
  if (exponent === 0) return sign * mantissa * 2 ** -24;
  if (exponent === 31) return mantissa ? NaN : sign * Infinity;
  return sign * (1 + mantissa / 1024) * 2 ** (exponent - 15);
}

function int32AsFloat(i) {
  const view = new DataView(new ArrayBuffer(4));
  view.setInt32(0, i, true);
  return view.getFloat32(0, true);
}

function load(path) {
  const container = read(new Uint8Array(readFileSync(path)));
  const raw = container.keyValue['probekit.transform'];
  if (!raw) fail('no probekit.transform key/value entry');
  const text = new TextDecoder().decode(raw).replace(/\0+$/, '');
  const transform = JSON.parse(text);
  const res = [container.pixelWidth, container.pixelHeight / 2, container.pixelDepth / 3];
  return { container, transform, res };
}

function checkContainer({ container, res }) {
  const expect = (what, got, want) => {
    if (got !== want) fail(`${what}: ${got}, expected ${want}`);
  };
  expect('vkFormat', container.vkFormat, VK_FORMAT_R16G16B16A16_SFLOAT);
  expect('typeSize', container.typeSize, 2);
  expect('pixelHeight divisible by 2', container.pixelHeight % 2, 0);
  expect('pixelDepth divisible by 3', container.pixelDepth % 3, 0);
  expect('layerCount', container.layerCount, 0);
  expect('faceCount', container.faceCount, 1);
  expect('levelCount', container.levelCount, 1);
  expect('supercompressionScheme', container.supercompressionScheme, 0);
  expect('KTXwriter', container.keyValue.KTXwriter, 'probekit');
  const dfd = container.dataFormatDescriptor[0];
  expect('DFD colorModel', dfd.colorModel, KHR_DF_MODEL_RGBSDA);
  expect('DFD colorPrimaries', dfd.colorPrimaries, KHR_DF_PRIMARIES_BT709);
  expect('DFD transferFunction', dfd.transferFunction, KHR_DF_TRANSFER_LINEAR);
  expect('DFD bytesPlane0', dfd.bytesPlane[0], 8);
  expect('DFD samples', dfd.samples.length, 4);
  [0, 1, 2, 15].forEach((channel, i) => {
    const s = dfd.samples[i];
    expect(`sample ${i} bitOffset`, s.bitOffset, 16 * i);
    expect(`sample ${i} bitLength`, s.bitLength, 15);
    expect(`sample ${i} channelType`, s.channelType, 0x80 | 0x40 | channel);
    expect(`sample ${i} sampleLower`, int32AsFloat(s.sampleLower), -1);
    expect(`sample ${i} sampleUpper`, int32AsFloat(s.sampleUpper), 1);
  });
  const level = container.levels[0];
  const texels = res[0] * 2 * res[1] * 3 * res[2];
  expect('level byteLength', level.levelData.byteLength, texels * 8);
  expect('level uncompressedByteLength', level.uncompressedByteLength, texels * 8);
  expect('level offset alignment', level.levelData.byteOffset % 8, 0);
}

function* voxels(res) {
  for (let z = 0; z < res[2]; z++)
    for (let y = 0; y < res[1]; y++)
      for (let x = 0; x < res[0]; x++) yield [x, y, z];
}

const AXES = [[1, 0, 0], [-1, 0, 0], [0, 1, 0], [0, -1, 0], [0, 0, 1], [0, 0, -1]];

function printPoints({ transform, res }) {
  const rows = ['x,y,z,nx,ny,nz'];
  for (const v of voxels(res)) {
    const p = [0, 1, 2].map(
      (a) => transform.translation[a] + ((v[a] + 0.5) / res[a] - 0.5) * transform.scale[a]);
    for (const n of AXES) rows.push([...p, ...n].join(','));
  }
  console.log(rows.join('\n'));
}

function texel(container, res, t) {
  const width = res[0], height = 2 * res[1];
  const data = container.levels[0].levelData;
  const view = new DataView(data.buffer, data.byteOffset, data.byteLength);
  const i = 8 * (t[0] + width * (t[1] + height * t[2]));
  return [0, 1, 2, 3].map((c) => halfToFloat(view.getUint16(i + 2 * c, true)));
}

function checkTexels(loaded, sampledPath) {
  const { container, res } = loaded;
  const lines = readFileSync(sampledPath, 'utf8').trim().split('\n').slice(1);
  const e = lines.map((l) => l.split(',').slice(6, 9).map(Number));
  if (e.length !== 6 * res[0] * res[1] * res[2]) fail(`${sampledPath}: ${e.length} rows`);
  const expected = [];
  let largest = 0;
  e.forEach((_, row) => {
    if (row % 2) return;
    const plus = e[row], minus = e[row + 1];
    for (const sign of [1, -1]) {
      const face = [0, 1, 2].map(
        (c) => Math.max(0, (plus[c] + minus[c]) / 2 + (sign * 1.25 * (plus[c] - minus[c])) / 2)
          / Math.PI);
      expected.push(face);
      largest = Math.max(largest, ...face);
    }
  });
  let worst = 0, count = 0;
  let k = 0;
  for (const v of voxels(res)) {
    for (let f = 0; f < 6; f++, k++) {
      const axis = f >> 1, negative = f & 1;
      const t = [v[0], v[1] + (negative ? res[1] : 0), v[2] + axis * res[2]];
      const got = texel(container, res, t);
      if (got[3] !== 1) fail(`alpha at ${t} is ${got[3]}`);
      for (let c = 0; c < 3; c++) {
        const want = expected[k][c];
        const tol = HALF_RELATIVE * Math.abs(want) + SAMPLING_RELATIVE * largest;
        const d = Math.abs(got[c] - want);
        worst = Math.max(worst, d / largest);
        if (!(d <= tol))
          fail(`voxel ${v} face ${'+-'[negative]}${'XYZ'[axis]} channel ${c}: texel ${t} holds ` +
               `${got[c]}, expected ${want} (tolerance ${tol})`);
        count++;
      }
    }
  }
  console.log(`bevy_ktx_parse: ${res.join('x')} voxels, ${count} texel values match ` +
              `(largest difference ${worst.toExponential(2)} of the largest face)`);
}

const [mode, file, sampled] = process.argv.slice(2);
const loaded = load(file);
if (mode === 'points') {
  printPoints(loaded);
} else if (mode === 'check') {
  checkContainer(loaded);
  checkTexels(loaded, sampled);
} else {
  fail('usage: bevy_ktx_parse.mjs points FILE.ktx2 | check FILE.ktx2 SAMPLED.csv');
}
