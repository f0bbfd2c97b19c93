// Regenerate src/api/schema.d.ts from the OpenAPI schema (`npm run gen:api`, or `make frontend-api`).
// With DRIFTMAP_URL set (e.g. http://127.0.0.1:8000) it reads `$DRIFTMAP_URL/api/openapi.json` from a running
// server; otherwise it dumps `create_app().openapi()` with the repository's Python (../.venv/bin/python, or
// $PYTHON).
//
// `--check` (`npm run check:api`, run by `make frontend-lint`) writes nothing: it generates into a scratch
// folder, compares with the committed file and exits 1 with the first differences when they differ.
import { execFileSync } from "node:child_process";
import { mkdtempSync, readFileSync, rmSync, writeFileSync } from "node:fs";
import { tmpdir } from "node:os";
import { join } from "node:path";

const committed = "src/api/schema.d.ts";
const check = process.argv.includes("--check");
const scratch = mkdtempSync(join(tmpdir(), "driftmap-openapi-"));

/** The OpenAPI document's location: the running server's URL, or a JSON file dumped from the app. */
function openapiSource() {
  if (process.env.DRIFTMAP_URL) return `${process.env.DRIFTMAP_URL.replace(/\/$/, "")}/api/openapi.json`;
  const python = process.env.PYTHON ?? "../.venv/bin/python";
  const code =
    "import json, sys\n" +
    "from driftmap.api.app import create_app\n" +
    "from driftmap.config import Settings\n" +
    "app = create_app(Settings(data_dir=sys.argv[1]))\n" +
    "print(json.dumps(app.openapi()))\n";
  const schema = execFileSync(python, ["-c", code, scratch], { encoding: "utf8", maxBuffer: 64 << 20 });
  const source = join(scratch, "openapi.json");
  writeFileSync(source, schema);
  return source;
}

/** The first lines where ``a`` and ``b`` differ, as a short unified-style excerpt. */
function firstDifferences(a, b, limit = 20) {
  const left = a.split("\n");
  const right = b.split("\n");
  const out = [];
  for (let i = 0; i < Math.max(left.length, right.length) && out.length < limit; i++) {
    if (left[i] === right[i]) continue;
    if (left[i] !== undefined) out.push(`${i + 1}: - ${left[i]}`);
    if (right[i] !== undefined) out.push(`${i + 1}: + ${right[i]}`);
  }
  return out.join("\n");
}

try {
  const out = check ? join(scratch, "schema.d.ts") : committed;
  execFileSync("npx", ["openapi-typescript", openapiSource(), "-o", out], { stdio: check ? "pipe" : "inherit" });
  if (check) {
    const want = readFileSync(out, "utf8");
    const have = readFileSync(committed, "utf8");
    if (want !== have) {
      console.error(
        `frontend/${committed} does not match the server's OpenAPI schema ` +
          "(- committed, + generated from the app):\n" +
          firstDifferences(have, want) +
          "\n\nRegenerate it with `make frontend-api` (or `cd frontend && npm run gen:api`) and commit it.",
      );
      process.exitCode = 1;
    } else {
      console.log(`frontend/${committed} matches the server's OpenAPI schema.`);
    }
  }
} finally {
  rmSync(scratch, { recursive: true, force: true });
}
