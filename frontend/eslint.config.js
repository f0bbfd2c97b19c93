// ESLint for the browser UI (`npm run lint`, run by `make frontend-lint`): typescript-eslint's type-aware
// recommended rules, the React hooks rules, and nothing about layout (Prettier owns that: `npm run format`).
import js from "@eslint/js";
import prettier from "eslint-config-prettier";
import reactHooks from "eslint-plugin-react-hooks";
import globals from "globals";
import tseslint from "typescript-eslint";

export default tseslint.config(
  { ignores: ["dist/", "node_modules/", "src/api/schema.d.ts"] },
  js.configs.recommended,
  {
    files: ["src/**/*.{ts,tsx}"],
    extends: [tseslint.configs.recommendedTypeChecked, reactHooks.configs.flat.recommended],
    languageOptions: {
      globals: globals.browser,
      parserOptions: { projectService: true, tsconfigRootDir: import.meta.dirname },
    },
    rules: {
      // `const { type: _, ...rest } = message` drops a field on purpose
      "@typescript-eslint/no-unused-vars": ["error", { ignoreRestSiblings: true }],
    },
  },
  {
    files: ["*.{js,ts}", "scripts/**/*.mjs"],
    extends: [tseslint.configs.recommended],
    languageOptions: { globals: globals.node },
  },
  prettier,
);
