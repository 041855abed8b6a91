// The JavaScript decoder against the Rust core on the shared capture sequences
// (../shared/data, outside the repository; skipped when absent): the Python command line
// encodes the first frames of each and prints the core's hashes, which the JS decoder must
// reproduce. Needs the dynmesh Python package (PYTHON, default python3): without it the
// tests skip and say why, except in CI (CI set, as .ci/run does), where the set-up installs
// the package and its absence is a failure.
import { test } from 'node:test';
import assert from 'node:assert/strict';
import { execFileSync, spawnSync } from 'node:child_process';
import { existsSync, mkdtempSync, readFileSync, rmSync } from 'node:fs';
import { tmpdir } from 'node:os';
import { join } from 'node:path';
import { fileURLToPath } from 'node:url';
import { Decoder } from '../src/index.js';
import { frameHash } from '../src/hash.js';

const SHARED = fileURLToPath(new URL('../../../shared/data/', import.meta.url));
const PYTHON = process.env.PYTHON || 'python3';
const SEQUENCES = ['basketball_player', 'thomas', 'horse_gallop', 'collision'];
const IN_CI = Boolean(process.env.CI);

// Why the Python side cannot run (a sentence), or null when `PYTHON -m dynmesh` works.
function pythonMissing() {
  const probe = spawnSync(PYTHON, ['-c', 'import dynmesh'], { encoding: 'utf8' });
  if (probe.error) return `${PYTHON} cannot be run (${probe.error.code}): set PYTHON to the virtualenv's python`;
  if (probe.status !== 0) {
    const last = (probe.stderr || '').trim().split('\n').pop();
    return `${PYTHON} cannot import dynmesh (${last}): activate the virtualenv or set PYTHON`;
  }
  return null;
}

const present = SEQUENCES.filter((name) => existsSync(join(SHARED, name)));
const noPython = present.length > 0 ? pythonMissing() : null;

if (noPython && IN_CI) {
  test('the Python environment for the shared-data tests', () => {
    assert.fail(`CI is set and ../shared/data is present, but ${noPython}`);
  });
}

for (const name of SEQUENCES) {
  const skip = !present.includes(name) ? `../shared/data/${name} is absent`
    : noPython && !IN_CI ? noPython : false;
  test(`JS equals Rust on ${name}`, { skip }, () => {
    const dir = mkdtempSync(join(tmpdir(), 'dynmesh-shared-'));
    try {
      const stream = join(dir, `${name}.dmsh`);
      execFileSync(PYTHON, ['-m', 'dynmesh', 'encode', join(SHARED, name), '--count', '3', '-o', stream, '-q'], { stdio: 'pipe' });
      for (const lod of [undefined, 1]) {
        const args = ['-m', 'dynmesh', 'decode', stream, '--hash', ...(lod === undefined ? [] : ['--lod', String(lod)])];
        const rust = execFileSync(PYTHON, args, { encoding: 'utf8' });
        const dec = new Decoder(new Uint8Array(readFileSync(stream)), { lod });
        const js = Array.from({ length: dec.frameCount }, (_, i) => `frame ${i} sha256 ${frameHash(dec.decodeFrame(i))}\n`).join('');
        assert.equal(js, rust, `lod ${lod ?? 'full'}`);
        assert.equal(rust.split('\n').length, 4);
      }
    } finally {
      rmSync(dir, { recursive: true, force: true });
    }
  });
}
