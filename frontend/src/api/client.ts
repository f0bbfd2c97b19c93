// A thin typed fetch wrapper over the generated OpenAPI types (src/api/schema.d.ts, `npm run gen:api`).
import type { components, paths } from "./schema";
import { dispositionFilename } from "../lib/exports";

export type Schemas = components["schemas"];

type JsonOf<R> = R extends { content: { "application/json": infer J } } ? J : undefined;
type Ok<O> = O extends { responses: infer Rs }
  ? 200 extends keyof Rs
    ? JsonOf<Rs[200]>
    : 201 extends keyof Rs
      ? JsonOf<Rs[201]>
      : 202 extends keyof Rs
        ? JsonOf<Rs[202]>
        : undefined
  : never;
type BodyOf<O> = O extends { requestBody: { content: { "application/json": infer B } } } ? B : never;
type Method = "get" | "post" | "patch" | "put" | "delete";
type PathsWith<M extends Method> = { [P in keyof paths]: paths[P][M] extends undefined ? never : P }[keyof paths];
type Op<P extends keyof paths, M extends Method> = NonNullable<paths[P][M]>;

/** A downloaded file's object URL is released this long after the click (the browser has taken it by then). */
const REVOKE_AFTER_MS = 60_000;

export type Query = Record<string, string | number | boolean | null | undefined>;

/** An error answer of the API: its HTTP status, the text to show, and the problem it came with (if any). */
export class ApiError extends Error {
  constructor(
    readonly status: number,
    message: string,
    readonly problem: Problem | null = null,
  ) {
    super(message);
  }
}

/** The body of every error answer: RFC 9457 problem details with driftmap's ``file``, ``line``, ``field``. */
export type Problem = Schemas["Problem"];

function issuesText(issues: unknown[]): string | null {
  const parts = issues.map((item: unknown) => {
    const { loc, msg } = (item ?? {}) as { loc?: unknown; msg?: unknown };
    const where = Array.isArray(loc) ? loc.filter((l) => l !== "body").join(".") : "";
    const text = typeof msg === "string" ? msg : JSON.stringify(item);
    return where ? `${where}: ${text}` : text;
  });
  return parts.length > 0 ? parts.join("; ") : null;
}

/**
 * The text of an error body: a problem's ``detail`` (with its ``field`` when the detail does not name it),
 * else its validation ``errors`` as "field: message; ..." (a ``detail`` list is read the same way), else its
 * ``title``. Null without any of them.
 */
export function detailText(body: {
  detail?: unknown;
  field?: unknown;
  errors?: unknown;
  title?: unknown;
}): string | null {
  const { detail, field, errors, title } = body;
  if (typeof detail === "string" && detail) {
    return typeof field === "string" && field && !detail.includes(field) ? `${field}: ${detail}` : detail;
  }
  if (Array.isArray(detail)) return issuesText(detail);
  if (Array.isArray(errors)) return issuesText(errors);
  if (typeof title === "string" && title) return title;
  return detail === undefined || detail === null ? null : JSON.stringify(detail);
}

let token: string | null = null;
let onUnauthorized: (() => void) | null = null;

export function setToken(value: string | null): void {
  token = value;
}

export function getToken(): string | null {
  return token;
}

export function setUnauthorizedHandler(handler: (() => void) | null): void {
  onUnauthorized = handler;
}

/** ``/api/sites/{site_id}`` with ``{site_id: 3}`` and a query -> ``/api/sites/3?...``. */
export function buildUrl(path: string, params: Record<string, string | number> = {}, query: Query = {}): string {
  const filled = path.replace(/\{(\w+)\}/g, (_, name: string) => {
    const value = params[name];
    if (value === undefined) throw new Error(`missing path parameter ${name} for ${path}`);
    return encodeURIComponent(String(value));
  });
  const search = new URLSearchParams();
  for (const [key, value] of Object.entries(query)) {
    if (value !== undefined && value !== null) search.set(key, String(value));
  }
  const text = search.toString();
  return text ? `${filled}?${text}` : filled;
}

/** The ApiError of a refused answer, with the server's reason; a 401 logs the user out (the handler). */
async function refusal(response: Response): Promise<ApiError> {
  if (response.status === 401 && onUnauthorized) onUnauthorized();
  let detail = response.statusText || `HTTP ${response.status}`;
  let problem: Problem | null = null;
  try {
    const body = (await response.json()) as Record<string, unknown>;
    if (typeof body.status === "number" && typeof body.title === "string") problem = body as unknown as Problem;
    detail = detailText(body) ?? detail;
  } catch {
    /* not JSON */
  }
  return new ApiError(response.status, detail, problem);
}

async function send(method: string, url: string, body?: unknown): Promise<unknown> {
  const headers: Record<string, string> = {};
  if (token) headers.Authorization = `Bearer ${token}`;
  let payload: BodyInit | undefined;
  if (body instanceof FormData) payload = body;
  else if (body !== undefined) {
    headers["Content-Type"] = "application/json";
    payload = JSON.stringify(body);
  }
  const response = await fetch(url, { method: method.toUpperCase(), headers, body: payload });
  if (!response.ok) throw await refusal(response);
  if (response.status === 204) return undefined;
  const type = response.headers.get("content-type") ?? "";
  return type.includes("json") ? response.json() : response.text();
}

export function apiGet<P extends PathsWith<"get">>(
  path: P,
  params: Record<string, string | number> = {},
  query: Query = {},
): Promise<Ok<Op<P, "get">>> {
  return send("get", buildUrl(path, params, query)) as Promise<Ok<Op<P, "get">>>;
}

export function apiPost<P extends PathsWith<"post">>(
  path: P,
  params: Record<string, string | number>,
  body?: BodyOf<Op<P, "post">>,
): Promise<Ok<Op<P, "post">>> {
  return send("post", buildUrl(path, params), body) as Promise<Ok<Op<P, "post">>>;
}

export function apiPatch<P extends PathsWith<"patch">>(
  path: P,
  params: Record<string, string | number>,
  body: BodyOf<Op<P, "patch">>,
): Promise<Ok<Op<P, "patch">>> {
  return send("patch", buildUrl(path, params), body) as Promise<Ok<Op<P, "patch">>>;
}

export function apiDelete<P extends PathsWith<"delete">>(
  path: P,
  params: Record<string, string | number>,
): Promise<unknown> {
  return send("delete", buildUrl(path, params));
}

/** An image URL that carries the token (for <img>, which cannot send headers): uses the login cookie too. */
export function imageUrl(path: string): string {
  return path;
}

export function apiPut<P extends PathsWith<"put">>(
  path: P,
  params: Record<string, string | number>,
  body: BodyOf<Op<P, "put">>,
): Promise<Ok<Op<P, "put">>> {
  return send("put", buildUrl(path, params), body) as Promise<Ok<Op<P, "put">>>;
}

/** POST a multipart form (e.g. images to calibrate from) to a route. */
export function apiPostForm<P extends PathsWith<"post">>(
  path: P,
  params: Record<string, string | number>,
  form: FormData,
): Promise<Ok<Op<P, "post">>> {
  return send("post", buildUrl(path, params), form) as Promise<Ok<Op<P, "post">>>;
}

/**
 * POST a multipart form (a plan, a drive zip, a video) with the upload's progress: ``onProgress(loaded, total)``
 * in bytes as the browser sends it (fetch cannot tell). A refusal rejects with an ApiError and the reason.
 */
export function apiUploadForm<P extends PathsWith<"post">>(
  path: P,
  params: Record<string, string | number>,
  form: FormData,
  onProgress: (loaded: number, total: number) => void,
): Promise<Ok<Op<P, "post">>> {
  return new Promise((resolve, reject) => {
    const xhr = new XMLHttpRequest();
    xhr.open("POST", buildUrl(path, params));
    if (token) xhr.setRequestHeader("Authorization", `Bearer ${token}`);
    xhr.upload.onprogress = (e) => {
      if (e.lengthComputable) onProgress(e.loaded, e.total);
    };
    xhr.onload = () => {
      let body: unknown = undefined;
      try {
        body = JSON.parse(xhr.responseText);
      } catch {
        /* not JSON */
      }
      if (xhr.status >= 200 && xhr.status < 300) {
        resolve(body as Ok<Op<P, "post">>);
        return;
      }
      if (xhr.status === 401 && onUnauthorized) onUnauthorized();
      const reason = typeof body === "object" && body !== null ? detailText(body) : null;
      const detail = reason ?? (xhr.statusText || `HTTP ${xhr.status}`);
      reject(new ApiError(xhr.status, detail));
    };
    xhr.onerror = () => reject(new ApiError(0, "the upload failed: no answer from the server"));
    xhr.send(form);
  });
}

/** PUT a multipart form (e.g. a CSV upload) to a route. */
export function apiPutForm<P extends PathsWith<"put">>(
  path: P,
  params: Record<string, string | number>,
  form: FormData,
): Promise<Ok<Op<P, "put">>> {
  return send("put", buildUrl(path, params), form) as Promise<Ok<Op<P, "put">>>;
}

/**
 * Download a route's answer (with the bearer token) as a file: saved under the server's name for it
 * (``Content-Disposition``), else ``filename``; returns the name. A refusal throws an ApiError with the reason.
 */
export async function apiDownload(url: string, filename: string): Promise<string> {
  const response = await fetch(url, { headers: token ? { Authorization: `Bearer ${token}` } : {} });
  if (!response.ok) throw await refusal(response);
  const name = dispositionFilename(response.headers.get("content-disposition")) ?? filename;
  const href = URL.createObjectURL(await response.blob());
  const link = document.createElement("a");
  link.href = href;
  link.download = name;
  document.body.append(link);
  link.click();
  link.remove();
  setTimeout(() => URL.revokeObjectURL(href), REVOKE_AFTER_MS);
  return name;
}
