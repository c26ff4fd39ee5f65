// Local flat-earth frames, the same as twin-core's `geodesy::LocalFrame`:
// north = dlat * R_M, east = dlon * R_N cos(lat0), WGS-84 radii at the origin.

const A = 6378137.0;
const F = 1 / 298.257223563;
const E2 = 2 * F - F * F;
const DEG = Math.PI / 180;

export function radii(lat0Deg) {
  const s = Math.sin(lat0Deg * DEG);
  const d = 1 - E2 * s * s;
  const rn = A / Math.sqrt(d);
  return { rm: (rn * (1 - E2)) / d, rp: rn * Math.cos(lat0Deg * DEG) };
}

function wrapPi(a) {
  return ((((a + Math.PI) % (2 * Math.PI)) + 2 * Math.PI) % (2 * Math.PI)) - Math.PI;
}

/** The frame's origin from one point known in both: lat/lon and north/east. */
export function originOf(latDeg, lonDeg, northM, eastM) {
  let lat0 = latDeg;
  for (let i = 0; i < 3; i++) {
    const { rm } = radii(lat0);
    lat0 = latDeg - northM / rm / DEG;
  }
  const { rm, rp } = radii(lat0);
  return { lat0, lon0: lonDeg - eastM / rp / DEG, rm, rp };
}

/** Geodetic to north/east in a frame from `originOf`. */
export function toLocal(frame, latDeg, lonDeg) {
  return {
    n: (latDeg - frame.lat0) * DEG * frame.rm,
    e: wrapPi((lonDeg - frame.lon0) * DEG) * frame.rp,
  };
}

/** RFC 3339 to seconds since the epoch. */
export function epochS(text) {
  const ms = Date.parse(text);
  return Number.isFinite(ms) ? ms / 1000 : NaN;
}

export const toDeg = (rad) => (((rad / DEG) % 360) + 360) % 360;
