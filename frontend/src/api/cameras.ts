// The camera routes the generic client has no helper for: a JSON PUT (profiles, a vehicle's camera) and a
// multipart POST (board images for the intrinsics), with the login token; a refusal throws an ApiError with
// the server's reason, as the client's other calls do.
import { ApiError, buildUrl, detailText, getToken, type Schemas } from "./client";

async function send<T>(method: string, url: string, body: BodyInit, json: boolean): Promise<T> {
  const headers: Record<string, string> = {};
  const token = getToken();
  if (token) headers.Authorization = `Bearer ${token}`;
  if (json) headers["Content-Type"] = "application/json";
  const response = await fetch(url, { method, headers, body });
  if (!response.ok) {
    let detail = response.statusText || `HTTP ${response.status}`;
    try {
      detail = detailText((await response.json()) as { detail?: unknown }) ?? detail;
    } catch {
      /* not JSON */
    }
    throw new ApiError(response.status, detail);
  }
  return (await response.json()) as T;
}

/** ``POST /api/cameras/intrinsics`` with board images (``intrinsicsForm``). */
export function postIntrinsics(form: FormData): Promise<Schemas["IntrinsicsRead"]> {
  return send("POST", "/api/cameras/intrinsics", form, false);
}

/** ``PUT /api/camera-profiles/{id}``: change a profile's name, description or camera block. */
export function putProfile(id: number, body: Schemas["CameraProfileUpdate"]): Promise<Schemas["CameraProfileRead"]> {
  return send("PUT", buildUrl("/api/camera-profiles/{profile_id}", { profile_id: id }), JSON.stringify(body), true);
}

/** ``PUT /api/vehicles/{id}/camera {"profile": id}``: give the vehicle a copy of the profile's block. */
export function assignProfile(vehicleId: number, profileId: number): Promise<Schemas["VehicleCamera"]> {
  const url = buildUrl("/api/vehicles/{vehicle_id}/camera", { vehicle_id: vehicleId });
  return send("PUT", url, JSON.stringify({ profile: profileId }), true);
}
