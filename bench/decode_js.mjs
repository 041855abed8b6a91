// node bench/decode_js.mjs STREAM REPS [LOD]: decodes every frame of STREAM in order, REPS
// times (a fresh decoder each time), and prints JSON {frames, ms: [per-repetition mean
// milliseconds per frame]} for bench/bench_web.py. The first repetition includes JIT warm-up.
import { readFileSync } from 'node:fs';
import { Decoder } from '../web/src/index.js';

const [path, reps = '5', lod] = process.argv.slice(2);
const data = new Uint8Array(readFileSync(path));
const ms = [];
let frames = 0;
for (let r = 0; r < Number(reps); r++) {
  const t0 = performance.now();
  const dec = new Decoder(data, { lod: lod === undefined ? undefined : Number(lod) });
  for (let i = 0; i < dec.frameCount; i++) dec.decodeFrame(i);
  frames = dec.frameCount;
  ms.push((performance.now() - t0) / frames);
}
console.log(JSON.stringify({ frames, ms }));
