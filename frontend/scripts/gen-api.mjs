// Regenerate src/api/schema.d.ts from the OpenAPI schema.
// With DRIFTMAP_URL set (e.g. http://127.0.0.1:8000) it reads `$DRIFTMAP_URL/api/openapi.json` from a running
// server; otherwise it dumps `create_app().openapi()` with the repository's Python (../.venv/bin/python).
import { execFileSync } from "node:child_process";
import { mkdtempSync, rmSync, writeFileSync } from "node:fs";
import { tmpdir } from "node:os";
import { join } from "node:path";

const out = "src/api/schema.d.ts";
let source;
let scratch = null;
if (process.env.DRIFTMAP_URL) {
  source = `${process.env.DRIFTMAP_URL.replace(/\/$/, "")}/api/openapi.json`;
} else {
  const python = process.env.PYTHON ?? "../.venv/bin/python";
  const dir = mkdtempSync(join(tmpdir(), "driftmap-openapi-"));
  scratch = dir;
  const code =
    "import json, sys\n" +
    "from driftmap.api.app import create_app\n" +
    "from driftmap.config import Settings\n" +
    "app = create_app(Settings(data_dir=sys.argv[1]))\n" +
    "print(json.dumps(app.openapi()))\n";
  const schema = execFileSync(python, ["-c", code, dir], { encoding: "utf8", maxBuffer: 64 << 20 });
  source = join(dir, "openapi.json");
  writeFileSync(source, schema);
}
try {
  execFileSync("npx", ["openapi-typescript", source, "-o", out], { stdio: "inherit" });
} finally {
  if (scratch) rmSync(scratch, { recursive: true, force: true });
}
