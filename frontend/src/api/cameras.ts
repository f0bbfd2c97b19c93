// The camera routes: a JSON PUT (profiles, a vehicle's camera), multipart POSTs (board images for the
// intrinsics, a frame to preview) and the check of a camera against a stored drive, through the client (the login token; a refusal throws an ApiError with the
// server's reason and a 401 logs the user out, as every other call).
import { apiPost, apiPostForm, apiPut, type Schemas } from "./client";

/** ``POST /api/cameras/intrinsics`` with board images (``intrinsicsForm``). */
export function postIntrinsics(form: FormData): Promise<Schemas["IntrinsicsRead"]> {
  return apiPostForm("/api/cameras/intrinsics", {}, form);
}

/** ``PUT /api/camera-profiles/{id}``: change a profile's name, description or camera block. */
export function putProfile(id: number, body: Schemas["CameraProfileUpdate"]): Promise<Schemas["CameraProfileRead"]> {
  return apiPut("/api/camera-profiles/{profile_id}", { profile_id: id }, body);
}

/** ``PUT /api/vehicles/{id}/camera {"profile": id}``: give the vehicle a copy of the profile's block. */
export function assignProfile(vehicleId: number, profileId: number): Promise<Schemas["VehicleCamera"]> {
  return apiPut("/api/vehicles/{vehicle_id}/camera", { vehicle_id: vehicleId }, { profile: profileId });
}

/** ``POST /api/cameras/preview`` (``previewForm``): the frame's undistorted image and bird's-eye view. */
export function postPreview(form: FormData): Promise<Schemas["PreviewRead"]> {
  return apiPostForm("/api/cameras/preview", {}, form);
}

/**
 * ``POST /api/drives/{id}/camera-check``: a camera (``body.camera``, else the drive's own) checked against a stored
 * drive; the server dead-reckons the drive while the request waits (up to about 30 s).
 */
export function postCameraCheck(
  driveId: number,
  body: Schemas["CameraCheckRequest"],
): Promise<Schemas["CameraCheckRead"]> {
  return apiPost("/api/drives/{drive_id}/camera-check", { drive_id: driveId }, body);
}
