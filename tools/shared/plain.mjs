// What the Node.js checks of tools/ share (no dependencies, imported by relative path).

// JSON-safe copy of a decoded message: bigint as string, typed arrays as arrays.
export function plain(value) {
  if (typeof value === 'bigint') return value.toString();
  if (ArrayBuffer.isView(value)) return Array.from(value, plain);
  if (Array.isArray(value)) return value.map(plain);
  if (value && typeof value === 'object') {
    return Object.fromEntries(Object.entries(value).map(([k, v]) => [k, plain(v)]));
  }
  return value;
}
