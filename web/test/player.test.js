// The player's worker (player/worker.js) fed a stream in small chunks, as a download gives
// it: every frame is decoded once its bytes are in, each texture group's unit comes before
// its frames, and the frames equal those of the stream given whole; a stream cut short fails
// with the decoder's message. And the three.js example's decoding (examples/threejs/frames.js).
import { test } from 'node:test';
import assert from 'node:assert/strict';
import { readFileSync } from 'node:fs';
import { fileURLToPath } from 'node:url';
import { Decoder } from '../src/index.js';

const DIR = fileURLToPath(new URL('../../tests/vectors/', import.meta.url));
const TEXTURED = new Uint8Array(readFileSync(DIR + 'textured_mixed.dmsh'));
const PLAIN = new Uint8Array(readFileSync(DIR + 'anchor_refresh.dmsh'));

// The worker's global scope: its posts are collected; `wait` resolves at `done` or `error`.
let out = [], ended = null;
globalThis.self = { postMessage: (m) => { out.push(m); if (m.done || m.error) ended?.(); } };
await import('../player/worker.js');

/** Feeds `bytes` to the worker in `size`-byte chunks (after each, its posts so far are
 * recorded), then the end; resolves with the posts and, per chunk, how many frames were in. */
async function feed(bytes, size) {
  out = [];
  const finished = new Promise((resolve) => { ended = resolve; });
  const send = (data) => self.onmessage({ data });
  send({ start: { lod: null, token: 1, first: 0 } });
  const arrivedAfter = [];
  for (let at = 0; at < bytes.length; at += size) {
    send({ chunk: bytes.slice(at, at + size).buffer });
    arrivedAfter.push(out.filter((m) => m.arrived !== undefined).pop()?.arrived ?? 0);
    await new Promise((resolve) => setTimeout(resolve, 0)); // lets the worker decode
  }
  send({ end: true });
  await finished;
  return { posts: out, arrivedAfter };
}

for (const [name, bytes] of [['textured', TEXTURED], ['untextured', PLAIN]]) {
  test(`the worker decodes the ${name} stream as it arrives, as it does the stream given whole`, async () => {
    const dec = new Decoder(bytes);
    const n = dec.frameCount;
    const streamed = await feed(bytes, 97);
    const posts = streamed.posts;
    assert.ok(!posts.some((m) => m.error), JSON.stringify(posts.find((m) => m.error)));
    assert.equal(posts[0].header.frameCount, n); // the header first
    // Frames arrive one by one over the chunks, not all at the end.
    assert.ok(streamed.arrivedAfter.filter((a) => a > 0 && a < n).length >= n - 1, String(streamed.arrivedAfter));
    const arrived = posts.filter((m) => m.infos);
    assert.deepEqual(arrived.flatMap((m) => m.infos), Array.from({ length: n }, (_, i) => dec.frameInfo(i)));
    assert.ok(arrived.pop().complete);
    // Each texture group's unit before any frame of the group.
    const order = posts.map((m) => (m.texture ? ['t', m.texture.first] : m.frame ? ['f', m.frame.index] : null)).filter(Boolean);
    const groups = order.filter(([k]) => k === 't').map(([, f]) => f);
    assert.deepEqual(groups, Array.from({ length: n }, (_, i) => i).filter((i) => dec.texturePayload(i) !== null));
    const at = (kind, i) => order.findIndex(([k, j]) => k === kind && j === i);
    for (let i = 0; i < n && groups.length; i++) assert.ok(at('t', Math.max(...groups.filter((g) => g <= i))) < at('f', i), `frame ${i}`);
    // The same frames as from the stream whole.
    out = [];
    const whole = new Promise((resolve) => { ended = resolve; });
    self.onmessage({ data: { stream: bytes.slice().buffer, lod: null, token: 2, first: 0 } });
    await whole;
    const frames = (posts) => posts.filter((m) => m.frame).map((m) => m.frame).sort((a, b) => a.index - b.index);
    assert.deepEqual(frames(posts), frames(out));
    assert.equal(frames(posts).length, n);
  });
}

test('a stream cut short, or with bytes after its last frame, fails as the decoder says', async () => {
  for (const bytes of [PLAIN.subarray(0, PLAIN.length - 5), Uint8Array.of(...PLAIN, 0), PLAIN.subarray(0, 40)]) {
    let message;
    try { new Decoder(bytes); } catch (e) { message = e.message; }
    assert.ok(message);
    const { posts } = await feed(bytes, 101);
    assert.equal(posts.find((m) => m.error)?.error, message);
  }
});

test('the three.js example decodes frames for a BufferGeometry', async () => {
  const { MeshFrames } = await import('../examples/threejs/frames.js');
  for (const bytes of [TEXTURED, PLAIN]) {
    const frames = new MeshFrames(bytes), dec = new Decoder(bytes);
    assert.equal(frames.count, dec.frameCount);
    for (let i = 0; i < frames.count; i++) {
      const f = frames.frame(i), { positions, faces } = dec.decodeFrame(i);
      if (f.uvs) {
        assert.equal(f.index, null);
        assert.equal(f.positions.length, 3 * faces.length);
        assert.equal(f.uvs.length, 2 * faces.length);
        assert.ok(f.uvs.every((u) => u >= 0 && u <= 1));
        assert.equal(f.positions[3], Math.fround(positions[3 * faces[1]]));
      } else {
        assert.deepEqual(f.index, faces);
        assert.deepEqual(f.positions, Float32Array.from(positions));
      }
    }
    assert.equal(await frames.image(0), null); // no WebCodecs in Node
  }
  // main.js takes from frames.js only what it exports.
  const main = readFileSync(new URL('../examples/threejs/main.js', import.meta.url), 'utf8');
  const names = [...main.matchAll(/import \{([^}]*)\} from '\.\/frames\.js'/g)].flatMap((m) => m[1].split(',').map((s) => s.trim()));
  const frames = await import('../examples/threejs/frames.js');
  assert.ok(names.length > 0 && names.every((x) => x in frames), names.join());
});
