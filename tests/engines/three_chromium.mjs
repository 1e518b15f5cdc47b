// Per-pixel check of the three.js export in a real browser (tests/engines/three_chromium_test.sh
// runs it): Chromium (SwiftShader WebGL) draws white Lambert surfaces lit only by the exported
// grid into a float target; each pixel's irradiance (pi x its value) is compared with
// `probekit sample` at the point three.js samples (the fragment's position plus half a probe
// spacing along its normal, per axis) with the fragment's normal.
//
//   node three_chromium.mjs ROOT WORKDIR PROBEKIT CASES_JSON
// CASES_JSON: [{name, gltf, pvol, grid, visibility, eye, target, fov, size, median, max,
//               picture?, exposure?, pictureSize?}
//              or {name, type: "leak", grid, pvol, reference, xs, ys, zs, bound}], paths
// relative to WORKDIR. Prints one line per case and exits 1 when a median or max relative error
// exceeds its tolerance, or a leak its bound. Writes WORKDIR/NAME-*.csv and NAME-*.json.
import { execFileSync } from 'node:child_process';
import { existsSync, readFileSync, writeFileSync } from 'node:fs';
import { createServer } from 'node:http';
import { extname, join, normalize, resolve } from 'node:path';
import { pathToFileURL } from 'node:url';

const [root, work, probekit, casesJson] = process.argv.slice(2);
const cases = JSON.parse(casesJson);
const integrations = join(root, 'integrations');
const puppeteerPath = join(integrations, 'node_modules/puppeteer-core/lib/esm/puppeteer/puppeteer-core.js');
const puppeteer = (await import(pathToFileURL(puppeteerPath))).default;

const types = { '.html': 'text/html', '.js': 'text/javascript', '.json': 'application/json',
                '.gltf': 'model/gltf+json', '.bin': 'application/octet-stream' };
const mounts = [['/node_modules/', join(integrations, 'node_modules')],
                ['/integrations/three/', join(integrations, 'three')],
                ['/work/', work],
                ['/page.html', join(root, 'tests/engines/three_page.html')]];

function servePath(url) {
    const path = decodeURIComponent(new URL(url, 'http://x').pathname);
    for (const [prefix, dir] of mounts) {
        if (prefix === path) return dir;
        if (prefix.endsWith('/') && path.startsWith(prefix)) {
            const file = normalize(join(dir, path.slice(prefix.length)));
            if (file.startsWith(dir)) return file;
        }
    }
    return null;
}

const server = createServer((request, response) => {
    if (request.url === '/favicon.ico') {
        response.writeHead(204).end();
        return;
    }
    const file = servePath(request.url);
    if (file === null || !existsSync(file)) {
        response.writeHead(404).end();
        return;
    }
    response.writeHead(200, { 'Content-Type': types[extname(file)] ?? 'application/octet-stream' });
    response.end(readFileSync(file));
});
await new Promise((done) => server.listen(0, '127.0.0.1', done));
const origin = `http://127.0.0.1:${server.address().port}`;

function chromium() {
    for (const candidate of ['/usr/lib/chromium/chromium', '/usr/bin/chromium'])
        if (existsSync(candidate)) return candidate;
    return 'chromium';
}

const browser = await puppeteer.launch({
    executablePath: process.env.PROBEKIT_CHROMIUM ?? chromium(),
    headless: true,
    args: ['--headless=new', '--no-sandbox', '--use-angle=swiftshader',
           '--enable-unsafe-swiftshader', '--ignore-gpu-blocklist'],
});

function percentile(sorted, p) {
    return sorted[Math.min(sorted.length - 1, Math.floor(p * sorted.length))];
}

// The fragments the grid lights, as three.js decides (sample point inside the bounds grown by
// 1% of a cell): their sample points and normals.
function fragments(m) {
    const min = m.bounds.min, max = m.bounds.max;
    const out = [];
    for (let i = 0; i < m.position.length / 4; ++i) {
        if (m.position[4 * i + 3] !== 1) continue;
        const length = Math.hypot(m.normal[4 * i], m.normal[4 * i + 1], m.normal[4 * i + 2]);
        if (!(Math.abs(length - 1) < 1e-3)) continue; // a degenerate triangle has no normal
        const q = [], n = [];
        let inside = true;
        for (let a = 0; a < 3; ++a) {
            const spacing = (max[a] - min[a]) / m.resolution[a];
            n.push(m.normal[4 * i + a]);
            q.push(m.position[4 * i + a] + 0.5 * n[a] * spacing);
            inside &&= q[a] >= min[a] - 0.01 * spacing && q[a] <= max[a] + 0.01 * spacing;
        }
        if (inside) out.push({ pixel: i, q, n });
    }
    return out;
}

function sampleAt(pvol, name, samples) {
    const points = join(work, `${name}-points.csv`);
    const sampled = join(work, `${name}-sampled.csv`);
    const lines = samples.map((s) => s.map((v) => v.toPrecision(9)).join(','));
    writeFileSync(points, ['x,y,z,nx,ny,nz', ...lines].join('\n') + '\n');
    execFileSync(probekit, ['sample', join(work, pvol), '--points', points, '-o', sampled],
                 { stdio: ['ignore', 'ignore', 'inherit'] });
    return readFileSync(sampled, 'utf8').trim().split('\n').slice(1)
        .map((line) => line.split(',').slice(6, 9).map(Number));
}

function sample(c, frags) {
    return sampleAt(c.pvol, c.name, frags.map((f) => [...f.q, ...f.n]));
}

// Relative error per pixel: the largest channel difference over the largest channel of
// probekit's E (floored at 1% of the median, so black corners do not divide by ~0).
function compare(m, frags, expected) {
    const brightest = expected.map((e) => Math.max(...e.map((v) => Math.max(v, 0))));
    const floor = 0.01 * percentile([...brightest].sort((a, b) => a - b), 0.5);
    const errors = frags.map((f, k) => {
        let worst = 0;
        for (let c = 0; c < 3; ++c) {
            const three = Math.PI * m.color[4 * f.pixel + c];
            worst = Math.max(worst, Math.abs(three - Math.max(expected[k][c], 0)));
        }
        return worst / Math.max(brightest[k], floor);
    });
    const sorted = [...errors].sort((a, b) => a - b);
    return { pixels: errors.length, median: percentile(sorted, 0.5),
             p99: percentile(sorted, 0.99), max: sorted[sorted.length - 1] };
}

const total = (rows) => rows.reduce((sum, e) => sum + e[0] + e[1] + e[2], 0);

// A leak case (tests/bake/test_leak.cpp's figure): points on the dark side of a thin wall, the
// six axis normals; sum of E over points, normals and channels against a path-traced
// reference (the reference volume's probes sit at exactly those points). three.js lights a
// surface at p from p + n spacing / 2, so its figure includes that offset.
async function leak(page, c) {
    const samples = [];
    for (const x of c.xs) for (const y of c.ys) for (const z of c.zs)
        for (const n of [[1, 0, 0], [-1, 0, 0], [0, 1, 0], [0, -1, 0], [0, 0, 1], [0, 0, -1]])
            samples.push([x, y, z, ...n]);
    const reference = total(sampleAt(c.reference, `${c.name}-reference`, samples));
    const grid = `/work/${c.grid}`;
    const plain = await page.evaluate((o) => window.probekitEvaluate(o),
                                      { grid, samples, visibility: false });
    const visible = await page.evaluate((o) => window.probekitEvaluate(o),
                                        { grid, samples, visibility: true });
    // probekit's sampler at three.js's sample points: what the visibility chunk must give.
    const header = JSON.parse(readFileSync(join(work, c.grid), 'utf8'));
    const spacing = [0, 1, 2].map((a) => (header.bounds.max[a] - header.bounds.min[a]) /
                                         header.resolution[a]);
    const shifted = samples.map((s) => [0, 1, 2].map((a) => s[a] + 0.5 * s[3 + a] * spacing[a])
                                                .concat(s.slice(3)));
    const stats = { samples: samples.length, threePlain: total(plain) / reference,
                    threeVisibility: total(visible) / reference,
                    probekit: total(sampleAt(c.pvol, `${c.name}-probekit`, samples)) / reference,
                    probekitAtThreePoints:
                        total(sampleAt(c.pvol, `${c.name}-shifted`, shifted)) / reference };
    writeFileSync(join(work, `${c.name}-leak.json`), JSON.stringify(stats, null, 2) + '\n');
    // The chunk must also be probekit's sampler at three.js's points (rounding: 1e-3).
    const ok = stats.threeVisibility <= c.bound &&
               Math.abs(stats.threeVisibility / stats.probekitAtThreePoints - 1) <= 1e-3;
    console.log(`${ok ? 'ok  ' : 'FAIL'} ${c.name}: leak (E / path reference, ${samples.length} ` +
                `samples) three.js ${stats.threePlain.toFixed(2)}x, with the visibility chunk ` +
                `${stats.threeVisibility.toFixed(3)}x (bound ${c.bound}); probekit sample ` +
                `${stats.probekit.toFixed(2)}x at the points, ` +
                `${stats.probekitAtThreePoints.toFixed(3)}x at three.js's sample points`);
    return ok;
}

let failed = false;
try {
    const page = await browser.newPage();
    page.on('console', (message) => {
        if (message.type() === 'error') console.error(`browser: ${message.text()}`);
    });
    page.on('pageerror', (error) => console.error(`browser: ${error.message}`));
    await page.goto(`${origin}/page.html`);
    await page.waitForFunction('window.probekitReady === true', { timeout: 30000 });
    for (const c of cases) {
        if (c.type === 'leak') {
            failed ||= !(await leak(page, c));
            continue;
        }
        const options = { ...c, grid: `/work/${c.grid}`, gltf: `/work/${c.gltf}` };
        const m = await page.evaluate((o) => window.probekitMeasure(o), options);
        const frags = fragments(m);
        const stats = compare(m, frags, sample(c, frags));
        writeFileSync(join(work, `${c.name}-errors.json`), JSON.stringify(stats, null, 2) + '\n');
        const ok = stats.pixels > 0 && stats.median <= c.median && stats.max <= c.max;
        failed ||= !ok;
        console.log(`${ok ? 'ok  ' : 'FAIL'} ${c.name}: ${stats.pixels} pixels, relative error ` +
                    `median ${stats.median.toExponential(2)} (tolerance ${c.median}), ` +
                    `p99 ${stats.p99.toExponential(2)}, max ${stats.max.toExponential(2)} ` +
                    `(tolerance ${c.max})`);
        if (c.picture) {
            const pictureOptions = { ...options, size: c.pictureSize ?? c.size };
            const url = await page.evaluate((o) => window.probekitPicture(o), pictureOptions);
            writeFileSync(resolve(root, c.picture), Buffer.from(url.split(',')[1], 'base64'));
            console.log(`wrote ${c.picture}`);
        }
    }
} finally {
    await browser.close();
    server.close();
}
process.exit(failed ? 1 : 0);
