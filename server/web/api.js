// A client of gvd.v1.VoronoiService over fetch, in the Connect protocol that gvd-server speaks on its
// HTTP port: unary calls as JSON, server-streaming calls as application/connect+json (each
// message behind a 5-byte envelope: flags, then the length in big-endian; the last envelope,
// flag 2, ends the stream and holds its error, if any).

export class GvdError extends Error {
  // code: the Connect code ("unauthenticated", "invalid_argument", ...); status: HTTP status.
  constructor(code, message, status) {
    super(message);
    this.code = code;
    this.status = status;
  }
  toString() {
    return `${this.code}: ${this.message}`;
  }
}

const decoder = new TextDecoder();
const encoder = new TextEncoder();
const kEndStream = 2;

function envelope(json) {
  const body = encoder.encode(json);
  const out = new Uint8Array(5 + body.length);
  new DataView(out.buffer).setUint32(1, body.length);
  out.set(body, 5);
  return out;
}

async function errorOf(response) {
  const text = await response.text();
  try {
    const body = JSON.parse(text);
    return new GvdError(body.code ?? 'unknown', body.message ?? `HTTP ${response.status}`, response.status);
  } catch {
    return new GvdError('unknown', `HTTP ${response.status}: ${text.slice(0, 200)}`, response.status);
  }
}

export class Client {
  // base: the server's HTTP origin ('' for the page's own); token: sent as a bearer token.
  constructor(base = '', token = '') {
    this.base = base;
    this.token = token;
  }

  headers(contentType) {
    const headers = { 'Content-Type': contentType };
    if (this.token) headers.Authorization = `Bearer ${this.token}`;
    return headers;
  }

  async post(method, contentType, body, signal) {
    try {
      return await fetch(`${this.base}/gvd.v1.VoronoiService/${method}`, {
        method: 'POST', headers: this.headers(contentType), body, signal,
      });
    } catch (e) {
      if (e.name === 'AbortError') throw e;
      throw new GvdError('unavailable', `the server cannot be reached (${e.message})`, 0);
    }
  }

  // A unary call: the response message as JSON (protobuf's canonical mapping: lowerCamelCase
  // fields, 64-bit integers as strings, fields at their default left out).
  async call(method, request, { signal } = {}) {
    const response = await this.post(method, 'application/json', JSON.stringify(request), signal);
    if (!response.ok) throw await errorOf(response);
    return response.json();
  }

  // A server-streaming call: onMessage(message) for each message; resolves when the server
  // ends the stream, rejects with its error (or when `signal` aborts).
  async stream(method, request, onMessage, { signal } = {}) {
    const response = await this.post(method, 'application/connect+json',
                                      envelope(JSON.stringify(request)), signal);
    if (!response.ok) throw await errorOf(response);
    const reader = response.body.getReader();
    let buffer = new Uint8Array(0);
    for (;;) {
      const { value, done } = await reader.read();
      if (done) break;
      const joined = new Uint8Array(buffer.length + value.length);
      joined.set(buffer);
      joined.set(value, buffer.length);
      buffer = joined;
      while (buffer.length >= 5) {
        const flags = buffer[0];
        const length = new DataView(buffer.buffer, buffer.byteOffset).getUint32(1);
        if (buffer.length < 5 + length) break;
        const message = JSON.parse(decoder.decode(buffer.subarray(5, 5 + length)) || '{}');
        buffer = buffer.slice(5 + length);
        if (flags & kEndStream) {
          if (message.error) {
            throw new GvdError(message.error.code ?? 'unknown', message.error.message ?? '', response.status);
          }
          return;
        }
        onMessage(message);
      }
    }
    throw new GvdError('unavailable', 'the stream broke off before its end', response.status);
  }
}

// The bytes of a protobuf `bytes` field, which JSON carries in base64.
export function bytesOf(base64) {
  const text = atob(base64 ?? '');
  const out = new Uint8Array(text.length);
  for (let i = 0; i < text.length; ++i) out[i] = text.charCodeAt(i);
  return out;
}
