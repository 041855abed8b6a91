// The syntax tables (src/stream/syntax.js) against docs/bitstream.md and against their Rust
// original core/src/stream/syntax.rs (parsed as text): the same constants with the same values,
// the same tables field for field; and the readers against the tables: bytes laid out as the
// tables say read back as the values written.
import { test } from 'node:test';
import assert from 'node:assert/strict';
import { readFileSync } from 'node:fs';
import * as syntax from '../src/stream/syntax.js';
import { readHeader, readUnits } from '../src/stream/bitstream.js';
import { readPayload } from '../src/decoder.js';
import { readTextureUnit } from '../src/texture/unit.js';
import { crc32 } from '../src/stream/crc32.js';

const { HEADER, FRAME_UNIT, INTRA_PAYLOAD, PREDICTED_PAYLOAD, TEXTURE_PAYLOAD, width, size, offset } = syntax;
const DOC = readFileSync(new URL('../../docs/bitstream.md', import.meta.url), 'utf8');
const RUST = readFileSync(new URL('../../core/src/stream/syntax.rs', import.meta.url), 'utf8');
const TABLES = { HEADER, FRAME_UNIT, INTRA_PAYLOAD, PREDICTED_PAYLOAD, TEXTURE_PAYLOAD };
const SECTIONS = [
  ['## 2. Sequence header', HEADER],
  ['## 3. Frame units', FRAME_UNIT],
  ['## 4. Intra payload', INTRA_PAYLOAD],
  ['## 4b. Predicted payload', PREDICTED_PAYLOAD],
  ['## 11. Texture unit payload', TEXTURE_PAYLOAD],
];

// ---- The document's notation ----

function typeText(field) {
  const c = field.count;
  if (field.ty === syntax.Ty.Bytes || (c.kind === 'N' && c.n === 1)) return field.ty;
  return `${field.ty}[${c.kind === 'N' ? c.n : c.kind === 'S' ? 'S' : c.sym}]`;
}

function sizeText(field) {
  const c = field.count, w = width(field.ty);
  if (c.kind === 'N') return String(c.n * w);
  if (c.kind === 'S') return w === 1 ? 'S' : `${w}S`;
  return c.sym;
}

function offsetText(fields, index, withOptional) {
  let constant = 0, k = 0;
  const syms = [];
  for (const field of fields.slice(0, index)) {
    if (field.optional && !withOptional) continue;
    const c = field.count;
    if (c.kind === 'N') constant += c.n * width(field.ty);
    else if (c.kind === 'S') k += width(field.ty);
    else syms.push(c.sym);
  }
  return String(constant) + (k === 0 ? '' : k === 1 ? '+S' : `+${k}S`) + syms.map((s) => `+${s}`).join('');
}

function docOffset(fields, index) {
  const optionalBefore = fields.slice(0, index).some((f) => f.optional);
  if (optionalBefore && !fields[index].optional) return `${offsetText(fields, index, false)}(${offsetText(fields, index, true)})`;
  return offsetText(fields, index, true);
}

/** The rows [offset, size, type, name] of the first table after `heading`. */
function docTable(heading) {
  const start = DOC.indexOf(`\n${heading}\n`);
  assert.ok(start >= 0, `no heading ${heading} in docs/bitstream.md`);
  const lines = DOC.slice(start + 1).split('\n').slice(1);
  const first = lines.findIndex((l) => l.startsWith('|'));
  const table = [];
  for (const l of lines.slice(first)) {
    if (!l.startsWith('|')) break;
    table.push(l.trim().replace(/^\||\|$/g, '').split(/(?<!\\)\|/).map((c) => c.trim()));
  }
  const head = table[0];
  const col = (name) => {
    const i = head.indexOf(name);
    assert.ok(i >= 0, `${heading}: no column ${name}`);
    return i;
  };
  const [o, s, t, n] = ['Offset', 'Size', 'Type', 'Name'].map(col);
  const clean = (x) => x.replace(/ /g, '');
  return table.slice(2).map((c) => [clean(c[o]), clean(c[s]), c[t], c[n].replace(/^`|`$/g, '')]);
}

test('the tables are the document\'s', () => {
  assert.ok(DOC.startsWith(`# The dynmesh bitstream (format version ${syntax.VERSION})`));
  for (const [heading, fields] of SECTIONS) {
    const rows = docTable(heading);
    assert.deepEqual(rows.map((r) => r[3]), fields.map((f) => f.name), `${heading}: field names and order`);
    fields.forEach((field, i) => {
      const ours = [docOffset(fields, i), sizeText(field), typeText(field), field.name];
      assert.deepEqual(rows[i], ours, `${heading}: field ${field.name} (offset, size, type, name)`);
    });
  }
  const expect = `**Header length** is ${syntax.HEADER_LEN} + ${syntax.HEADER_LEN_PER_ITERATION}S`;
  assert.ok(DOC.includes(expect), expect);
});

// ---- The Rust original, as text ----

/** `pub const NAME: TYPE = VALUE;` outside the tests, tables apart. */
function rustConstants() {
  const body = RUST.slice(0, RUST.indexOf('#[cfg(test)]'));
  const scalars = {}, tables = {};
  for (const m of body.matchAll(/^pub const (\w+): ([^=]+?) = ([^;]+|&\[[^\]]*\]);/gms)) {
    const [, name, type, value] = m;
    if (type.trim() === '&[Field]') {
      tables[name] = [...value.matchAll(/\b(f|opt)\("(\w+)", (\w+), (N\((\d+)\)|S|Len\("(\w+)"\))\)/g)].map((e) => ({
        name: e[2],
        ty: syntax.Ty[e[3]],
        count: e[5] !== undefined ? { kind: 'N', n: Number(e[5]) } : e[4] === 'S' ? { kind: 'S' } : { kind: 'Len', sym: e[6] },
        optional: e[1] === 'opt',
      }));
    } else if (/^b"(.*)"$/.test(value)) {
      scalars[name] = [...value.slice(2, -1)].map((c) => c.charCodeAt(0));
    } else {
      assert.match(value, /^[-\d\s<>+*[\]",a-z]+$/, `${name}: a literal`);
      scalars[name] = Function(`return ${value}`)();
    }
  }
  return { scalars, tables };
}

test('syntax.js declares the names and values of syntax.rs', () => {
  const { scalars, tables } = rustConstants();
  assert.ok(Object.keys(scalars).length >= 35, `parsed ${Object.keys(scalars).length} constants from syntax.rs`);
  const plain = (v) => JSON.parse(JSON.stringify(v));
  for (const [name, value] of Object.entries(scalars)) assert.deepEqual(plain(syntax[name]), value, name);
  assert.deepEqual(Object.keys(tables).sort(), Object.keys(TABLES).sort());
  for (const [name, fields] of Object.entries(tables)) assert.deepEqual(plain(TABLES[name]), fields, name);
  const ours = Object.keys(syntax).filter((k) => /^[A-Z][A-Z0-9_]+$/.test(k));
  assert.deepEqual(ours.sort(), [...Object.keys(scalars), ...Object.keys(tables)].sort(), 'upper-case exports of syntax.js');
});

test('the named offsets and lengths follow the tables', () => {
  const none = () => 0;
  for (let s = 0; s <= syntax.MAX_SUBDIV; s++) assert.equal(syntax.headerLen(s), offset(HEADER, 'header_crc', s, none, true) + 4);
  assert.equal(offset(HEADER, 'version', 0, none, true), syntax.HEADER_VERSION_AT);
  assert.equal(offset(HEADER, 'frame_count', 0, none, true), syntax.HEADER_FRAME_COUNT_AT);
  assert.equal(offset(FRAME_UNIT, 'length', 0, none, true), syntax.UNIT_LENGTH_AT);
  assert.equal(offset(FRAME_UNIT, 'payload', 0, none, true), syntax.UNIT_PAYLOAD_AT);
  assert.equal(offset(FRAME_UNIT, 'crc', 0, none, true), syntax.UNIT_OVERHEAD - 4);
  assert.equal(offset(TEXTURE_PAYLOAD, 'atlas_len', 0, none, true), syntax.TEXTURE_FIXED);
  assert.equal(syntax.MAGIC.length, size(HEADER[0], 0));
  assert.equal(syntax.TEXTURE_CODECS[syntax.TEXTURE_CODEC_HEVC], 'hevc');
  assert.equal(syntax.TEXTURE_CODECS[syntax.TEXTURE_CODEC_AV1], 'av1');
});

// ---- The readers against the tables ----

/**
 * The bytes of a structure laid out by its table: `values[name]` is a number (every element of
 * the field gets it), an array of elements, or the bytes of a block (its length field is filled
 * in). Fields without a value (optional ones) are left out; `header_crc`/`crc` get the CRC.
 */
function layout(fields, values, s) {
  const out = [];
  const put = (ty, v) => {
    const b = new DataView(new ArrayBuffer(8));
    const w = { u8: 1, '(u8, u8)': 1, u16: 2, u32: 4, i32: 4, f64: 8 }[ty];
    if (ty === 'f64') b.setFloat64(0, v, true);
    else if (ty === 'i32') b.setInt32(0, v, true);
    else if (ty === 'u32') b.setUint32(0, v, true);
    else if (ty === 'u16') b.setUint16(0, v, true);
    else b.setUint8(0, v);
    out.push(...new Uint8Array(b.buffer, 0, w));
  };
  fields.forEach((field, i) => {
    const next = fields[i + 1];
    if (field.name.endsWith('crc')) return put(field.ty, crc32(Uint8Array.from(out)));
    if (next && next.count.kind === 'Len' && values[next.name] !== undefined) return put(field.ty, values[next.name].length);
    const v = values[field.name];
    if (v === undefined) {
      assert.ok(field.optional, `${field.name} needs a value`);
      return;
    }
    if (field.count.kind === 'Len') return out.push(...v);
    const n = field.count.kind === 'N' ? field.count.n : s;
    const elements = field.ty === syntax.Ty.U8Pair ? 2 * n : n;
    for (let k = 0; k < elements; k++) put(field.ty, Array.isArray(v) ? v[k] : v);
  });
  return Uint8Array.from(out);
}

test('the readers find each field where the tables put it', () => {
  const values = {
    magic: syntax.MAGIC, version: syntax.VERSION, frame_count: 2, origin: [1.5, -2, 0.25], step: 0.01, bits: 12, base_bits: 10,
    subdiv_iterations: 3, schemes: [syntax.SCHEME_MIDPOINT, syntax.SCHEME_LOOP, syntax.SCHEME_LOOP], per_valence: syntax.FLAG_ON,
    update: [63, 80, 21, 20, 7, 5], components: syntax.COMPONENTS_ALL, aq: syntax.FLAG_ON, aq_alpha: 1.25, aq_delta: 0.25, aq_h: 6,
  };
  const header = layout(HEADER, values, 3);
  assert.equal(header.length, syntax.headerLen(3));
  const intra = layout(INTRA_PAYLOAD, { qp: -7, base_block: [1, 2, 3], coef_block: [9, 9] });
  const predicted = layout(PREDICTED_PAYLOAD, {
    reference_distance: 1, qp: 30, motion_block: [4], mode: syntax.MODE_REFRESH | syntax.MODE_COEFFICIENT_DIFFERENCES,
    refresh_block: [5, 5], coef_block: [6],
  });
  const unit = (type, payload) => layout(FRAME_UNIT, { frame_type: type, payload });
  const stream = Uint8Array.from([...header, ...unit(syntax.FRAME_INTRA, intra), ...unit(syntax.FRAME_PREDICTED, predicted)]);

  const h = readHeader(stream);
  assert.deepEqual(
    [h.frameCount, h.origin, h.step, h.bits, h.baseBits, h.schemes, h.lifting, h.components, h.aq, h.length],
    [2, [1.5, -2, 0.25], 0.01, 12, 10, [0, 1, 1], { update: [[63, 80], [21, 20], [7, 5]], perValence: true }, 3, { alpha: 1.25, delta: 0.25, h: 6 }, header.length],
  );
  const units = readUnits(stream, h);
  assert.deepEqual(units.map((u) => [u.type, u.length]), [[syntax.FRAME_INTRA, intra.length], [syntax.FRAME_PREDICTED, predicted.length]]);
  const p0 = readPayload(stream, units[0], 0);
  assert.deepEqual([p0.qp, [...p0.base], [...p0.coefficients], p0.coefficientsPredicted], [-7, [1, 2, 3], [9, 9], false]);
  assert.equal(p0.coefficientsOffset, units[0].offset + offset(INTRA_PAYLOAD, 'coef_block', 0, (s) => ({ B: 3 })[s], false));
  const p1 = readPayload(stream, units[1], 1);
  assert.deepEqual([p1.referenceDistance, p1.qp, [...p1.base], [...p1.refresh], [...p1.coefficients], p1.coefficientsPredicted], [1, 30, [4], [5, 5], [6], true]);
  const lens = (s) => ({ M: 1, R: 2 })[s];
  assert.equal(p1.refreshOffset, units[1].offset + offset(PREDICTED_PAYLOAD, 'refresh_block', 0, lens, true));
  assert.equal(p1.coefficientsOffset, units[1].offset + offset(PREDICTED_PAYLOAD, 'coef_block', 0, lens, true));

  const texture = layout(TEXTURE_PAYLOAD, {
    version: syntax.TEXTURE_PAYLOAD_VERSION, codec: syntax.TEXTURE_CODEC_AV1, width: 1024, height: 512, uv_bits: 12, frames: 3,
    atlas_block: [1, 2, 3], video_block: [8, 8, 8, 8, 8],
  });
  const t = readTextureUnit(texture);
  assert.deepEqual([t.codec, t.width, t.height, t.uvBits, t.frames, [...t.atlas], [...t.video]], ['av1', 1024, 512, 12, 3, [1, 2, 3], [8, 8, 8, 8, 8]]);
});
