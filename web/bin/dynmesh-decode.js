#!/usr/bin/env node
// dynmesh-decode STREAM [--hash] [--lod K] [--info]: decodes a .dmsh stream with the
// JavaScript decoder. --hash prints `frame N sha256 HEX` per frame, as `dynmesh decode --hash`.
import { readFileSync } from 'node:fs';
import { Decoder } from '../src/index.js';
import { frameHash } from '../src/hash.js';

const USAGE = 'usage: dynmesh-decode STREAM [--hash] [--lod K]';

function parse(argv) {
  const a = { stream: null, hash: false, lod: undefined };
  for (let i = 0; i < argv.length; i++) {
    const x = argv[i];
    if (x === '--hash') a.hash = true;
    else if (x === '--lod') {
      const v = argv[++i];
      if (v === undefined || !/^\d+$/.test(v)) throw new Error(`--lod needs a non-negative integer`);
      a.lod = Number(v);
    } else if (x === '-h' || x === '--help') { console.log(USAGE); process.exit(0); }
    else if (x.startsWith('-')) throw new Error(`unknown option ${x}`);
    else if (a.stream === null) a.stream = x;
    else throw new Error(`unexpected argument ${x}`);
  }
  if (a.stream === null) throw new Error(USAGE);
  return a;
}

function main() {
  try {
    const a = parse(process.argv.slice(2));
    let data;
    try {
      data = new Uint8Array(readFileSync(a.stream));
    } catch (e) {
      throw new Error(`cannot read ${a.stream}: ${e.code === 'ENOENT' ? 'No such file or directory' : e.message}`);
    }
    const dec = new Decoder(data, { lod: a.lod });
    const lines = [];
    let faces = 0;
    for (let i = 0; i < dec.frameCount; i++) {
      const f = dec.decodeFrame(i);
      faces += f.faces.length / 3;
      if (a.hash) lines.push(`frame ${i} sha256 ${frameHash(f)}`);
    }
    if (a.hash) process.stdout.write(lines.join('\n') + (lines.length ? '\n' : ''));
    else console.log(`decoded ${dec.frameCount} frames, ${faces} faces`);
    return 0;
  } catch (e) {
    console.error(`dynmesh-decode: error: ${e.message}`);
    return 1;
  }
}

process.exitCode = main();
