// 2^x rounded correctly to float64, for the level scale `2f64.powf(e)` of the Rust core.
//
// Why not Math.pow: V8's pow is not correctly rounded (2^0.5 comes out one ulp low), while
// the core's libm pow (glibc) is, on every exponent the format can produce (tests/vectors/
// scales.txt lists them all; test/scales.test.js checks this function against it). So 2^x
// is computed here in 160-bit fixed point with BigInt: x = n + f with f in [0, 1),
// 2^f = exp(f ln 2) by its Taylor series, rounded once to 53 bits, then scaled by 2^n.

const P = 160n; // fixed-point fraction bits
const ONE = 1n << P;

/** ln 2 = sum over k >= 1 of 1 / (k 2^k), to P bits. */
const LN2 = (() => {
  let s = 0n;
  for (let k = 1n; k < P + 8n; k++) s += ONE / (k << k);
  return s;
})();

/** The exact value of a float64 in [0, 1) as a P-bit fixed-point BigInt (f has <= 53 bits
 * after its binary point for |x| < 2^52, so this is exact). */
function fixed(f) {
  let m = f, e = 0;
  while (m !== Math.floor(m)) { m *= 2; e++; }
  return (BigInt(m) << P) >> BigInt(e);
}

const cache = new Map();

/**
 * @param {number} x a finite exponent with |x| < 1000
 * @returns {number} 2^x, correctly rounded (round to nearest, ties to even)
 */
export function pow2(x) {
  const hit = cache.get(x);
  if (hit !== undefined) return hit;
  const n = Math.floor(x);
  const f = x - n; // exact
  const y = (fixed(f) * LN2) >> P;
  let term = ONE, sum = ONE;
  for (let k = 1n; term > 0n; k++) {
    term = (term * y) / (k << P);
    sum += term;
  }
  // sum is in [1, 2): keep 52 fraction bits, round half to even on the rest.
  const drop = P - 52n;
  let mant = sum >> drop;
  const rest = sum & ((1n << drop) - 1n), half = 1n << (drop - 1n);
  if (rest > half || (rest === half && (mant & 1n) === 1n)) mant += 1n;
  const r = (Number(mant) / 2 ** 52) * 2 ** n;
  cache.set(x, r);
  return r;
}
