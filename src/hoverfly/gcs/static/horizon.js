// A 2D artificial horizon on a canvas, as an attitude indicator reads: the aircraft symbol is
// fixed, the horizon rolls against it (roll right: the horizon turns anticlockwise, its right side
// rising, as the world seen from a cockpit banking right) and moves down
// as the nose pitches up. Angles in degrees, roll and pitch positive right and up (FRD).

const SKY = "#2f6fb0";
const GROUND = "#7a5230";
const PX_PER_DEG = 3; // the ladder spans +-45 deg on a 360 px dial: enough for an angle-mode craft

export function drawHorizon(canvas, rollDeg, pitchDeg, yawDeg, live) {
  const g = canvas.getContext("2d");
  const w = canvas.width;
  const h = canvas.height;
  const cx = w / 2;
  const cy = h / 2;
  const scale = w / 360;
  g.save();
  g.clearRect(0, 0, w, h);

  g.translate(cx, cy);
  g.rotate((-rollDeg * Math.PI) / 180);
  g.translate(0, pitchDeg * PX_PER_DEG * scale);
  const big = w * 3;
  g.fillStyle = SKY;
  g.fillRect(-big, -big, 2 * big, big);
  g.fillStyle = GROUND;
  g.fillRect(-big, 0, 2 * big, big);
  g.strokeStyle = "#fff";
  g.lineWidth = 2 * scale;
  g.beginPath();
  g.moveTo(-big, 0);
  g.lineTo(big, 0);
  g.stroke();

  g.fillStyle = "#fff";
  g.font = `${11 * scale}px sans-serif`;
  g.textBaseline = "middle";
  g.lineWidth = 1.2 * scale;
  for (let d = -60; d <= 60; d += 10) {
    if (d === 0) continue;
    const y = -d * PX_PER_DEG * scale;
    const half = (d % 20 === 0 ? 40 : 22) * scale;
    g.beginPath();
    g.moveTo(-half, y);
    g.lineTo(half, y);
    g.stroke();
    if (d % 20 === 0) {
      g.fillText(String(Math.abs(d)), half + 4 * scale, y);
    }
  }
  g.restore();

  // Roll scale: ticks at 10, 20, 30, 45, 60 deg, and a pointer that turns with the craft.
  g.save();
  g.translate(cx, cy);
  g.strokeStyle = "#fff";
  g.lineWidth = 2 * scale;
  const r = w * 0.44;
  for (const d of [-60, -45, -30, -20, -10, 0, 10, 20, 30, 45, 60]) {
    const a = ((d - 90) * Math.PI) / 180;
    const len = (d % 30 === 0 ? 14 : 8) * scale;
    g.beginPath();
    g.moveTo(Math.cos(a) * r, Math.sin(a) * r);
    g.lineTo(Math.cos(a) * (r - len), Math.sin(a) * (r - len));
    g.stroke();
  }
  g.rotate((-rollDeg * Math.PI) / 180);
  g.fillStyle = "#ffd23f";
  g.beginPath();
  g.moveTo(0, -r + 16 * scale);
  g.lineTo(-7 * scale, -r + 28 * scale);
  g.lineTo(7 * scale, -r + 28 * scale);
  g.closePath();
  g.fill();
  g.restore();

  // The fixed aircraft symbol.
  g.save();
  g.translate(cx, cy);
  g.strokeStyle = "#ffd23f";
  g.lineWidth = 4 * scale;
  g.beginPath();
  g.moveTo(-70 * scale, 0);
  g.lineTo(-25 * scale, 0);
  g.lineTo(-12 * scale, 12 * scale);
  g.moveTo(70 * scale, 0);
  g.lineTo(25 * scale, 0);
  g.lineTo(12 * scale, 12 * scale);
  g.stroke();
  g.fillStyle = "#ffd23f";
  g.beginPath();
  g.arc(0, 0, 4 * scale, 0, 2 * Math.PI);
  g.fill();
  g.restore();

  // Heading, and a veil when the numbers are not live (so a frozen picture is not read as level).
  g.fillStyle = "#000a";
  g.fillRect(cx - 34 * scale, h - 34 * scale, 68 * scale, 22 * scale);
  g.fillStyle = "#fff";
  g.font = `${14 * scale}px monospace`;
  g.textAlign = "center";
  g.textBaseline = "middle";
  const hdg = ((Math.round(yawDeg) % 360) + 360) % 360;
  g.fillText(`${String(hdg).padStart(3, "0")}°`, cx, h - 23 * scale);
  if (!live) {
    g.fillStyle = "#000b";
    g.fillRect(0, 0, w, h);
    g.fillStyle = "#e5484d";
    g.font = `bold ${18 * scale}px sans-serif`;
    g.fillText("NO TELEMETRY", cx, cy);
  }
}
