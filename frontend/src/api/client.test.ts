import { afterEach, describe, expect, it, vi } from "vitest";
import { ApiError, apiGet, detailText } from "./client";
import { errorText } from "../views/useErrors";

const problem = {
  type: "about:blank",
  title: "Unprocessable Content",
  status: 422,
  detail: "limit: Input should be greater than or equal to 1",
  instance: "/api/jobs",
  file: null,
  line: null,
  field: "limit",
  errors: [{ type: "greater_than_equal", loc: ["query", "limit"], msg: "Input should be ...", input: "0" }],
};

describe("reading a problem answer", () => {
  afterEach(() => vi.unstubAllGlobals());

  it("shows the problem's detail, else its validation errors, else its title", () => {
    expect(detailText(problem)).toBe("limit: Input should be greater than or equal to 1");
    expect(detailText({ ...problem, detail: "" })).toBe("query.limit: Input should be ...");
    expect(detailText({ title: "Not Found" })).toBe("Not Found");
  });

  it("throws an ApiError carrying the status, the text and the problem", async () => {
    const body = JSON.stringify(problem);
    const answer = new Response(body, { status: 422, headers: { "Content-Type": "application/problem+json" } });
    vi.stubGlobal("fetch", vi.fn().mockResolvedValue(answer));
    const error = await apiGet("/api/jobs", {}, { limit: 0 }).catch((e: unknown) => e);
    expect(error).toBeInstanceOf(ApiError);
    expect((error as ApiError).status).toBe(422);
    expect((error as ApiError).problem?.field).toBe("limit");
    expect(errorText(error)).toBe("limit: Input should be greater than or equal to 1");
  });
});
