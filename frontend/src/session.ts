// Who is logged in: the token lives in sessionStorage (one login per tab) and goes out as a bearer header.
import { apiGet, apiPost, setToken, type Schemas } from "./api/client";

export type Me = Schemas["Me"];
export type Role = "admin" | "surveyor" | "viewer";
const KEY = "driftmap_token";

export function canEdit(me: Me | null): boolean {
  return me?.role === "admin" || me?.role === "surveyor";
}

export function isAdmin(me: Me | null): boolean {
  return me?.role === "admin";
}

export async function restore(): Promise<Me | null> {
  const saved = sessionStorage.getItem(KEY);
  if (!saved) return null;
  setToken(saved);
  try {
    return await apiGet("/api/auth/me");
  } catch {
    forget();
    return null;
  }
}

export async function login(username: string, password: string): Promise<Me> {
  const token = await apiPost("/api/auth/login", {}, { username, password });
  setToken(token.access_token);
  sessionStorage.setItem(KEY, token.access_token);
  return apiGet("/api/auth/me");
}

export function forget(): void {
  sessionStorage.removeItem(KEY);
  setToken(null);
}

export async function logout(): Promise<void> {
  try {
    await apiPost("/api/auth/logout", {});
  } finally {
    forget();
  }
}
