// The inverse lifting wavelet (`core/src/residual/transform.rs`, docs/bitstream.md section
// 8.4): per level, the parents' update undone in descending vertex order, then the midpoint
// prediction added back in ascending order.
//
// Contract: `inverseLifting` gives the Rust `transform::inverse` coefficients bit for bit,
// each expression in the Rust operation order.

/**
 * The update weight of each parent (vertices below `lod[level]`) for the step to `level`
 * (`transform.rs::Lifting::weights`): numerator / denominator, divided by the parent's
 * number of children at that level when `lifting.perValence`.
 */
function updateWeights(sub, lifting, level) {
  const lod = sub.lodOffsets, base = lod[1], par = sub.parents;
  const [num, den] = lifting.update[level - 1];
  const w = num / Math.max(den, 1);
  const out = new Float64Array(lod[level]);
  if (!lifting.perValence) return out.fill(w);
  const children = new Uint32Array(lod[level]);
  for (let v = lod[level]; v < lod[level + 1]; v++) {
    children[par[2 * (v - base)]]++;
    children[par[2 * (v - base) + 1]]++;
  }
  for (let p = 0; p < out.length; p++) out[p] = w / Math.max(children[p], 1);
  return out;
}

/** Inverse lifting over the levels of `sub`, in place on flat xyz `c`, with the header's `lifting`. */
export function inverseLifting(c, sub, lifting) {
  const lod = sub.lodOffsets, base = lod[1], par = sub.parents;
  for (let level = 1; level + 1 < lod.length; level++) {
    const w = updateWeights(sub, lifting, level);
    for (let v = lod[level + 1] - 1; v >= lod[level]; v--) {
      const pa = par[2 * (v - base)], pb = par[2 * (v - base) + 1];
      const a = 3 * pa, b = 3 * pb, i = 3 * v;
      for (let k = 0; k < 3; k++) {
        c[a + k] -= w[pa] * c[i + k];
        c[b + k] -= w[pb] * c[i + k];
      }
    }
    for (let v = lod[level]; v < lod[level + 1]; v++) {
      const a = 3 * par[2 * (v - base)], b = 3 * par[2 * (v - base) + 1], i = 3 * v;
      for (let k = 0; k < 3; k++) c[i + k] += 0.5 * (c[a + k] + c[b + k]);
    }
  }
}
