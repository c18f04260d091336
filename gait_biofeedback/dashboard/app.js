// Clinician dashboard of gait_biofeedback (thesis ch. 8, §9.2.5): stick figure, joint-angle curves over
// the reference band, IC/TC markers, gait parameters, activity, sensor status, cues and audio beeps.
// Data arrive over the websocket /ws of the biofeedback node in SI units (rad, s, Hz, fractions);
// degrees, percent and steps/min are used only for display. No third-party code, no build step.
"use strict";

const DEG = 180 / Math.PI;
const SIDES = ["left", "right"];
const CURVES = ["hip_flexion", "knee_flexion", "ankle_dorsiflexion"];
const CURVE_TITLES = { hip_flexion: "Hip flexion", knee_flexion: "Knee flexion", ankle_dorsiflexion: "Ankle dorsiflexion" };
const CURVE_RANGE = { hip_flexion: [-25, 50], knee_flexion: [-10, 75], ankle_dorsiflexion: [-30, 25] };
const COLORS = { left: "#1f77b4", right: "#e4572e", pelvis: "#555" };
const STRIDES_KEPT = 5;
const SAMPLES_KEPT = 600;     // ~6 s at 100 Hz
const EVENT_WINDOW = 6.0;     // s shown on the IC/TC strip
const PROGRESS_STATUS = "calibration: progress";  // the calibration node's /diagnostics status

// Everything the page knows; exposed for the browser test.
const state = {
  connected: false, hello: false, framesReceived: 0, framesRendered: 0, fps: 0,
  figureUpdates: 0, figureMotion: 0, curvePoints: 0, strideCurves: 0, samplesReceived: 0,
  events: 0, cuesReceived: 0, lastCalibration: null, lastReply: null, audio: null, muted: false,
  readOnly: true, calibrationInForce: null, proposedProtocol: null,
  lastAngleStamp: null, lastFrameWall: null, feedback: { side: "both", joint: "all" },
  ended: false, connectionLost: false, clippedLabels: 0, clippedLabelsNow: 0, calibrationProgress: "",
  instruction: null, instructionsReceived: 0, spoken: 0, lastSpoken: "", toneFallbacks: 0, coaching: null,
};
window.dashboardState = state;

const data = {
  targets: null, figure: null, angles: null, samples: [], strides: { left: [], right: [] },
  events: [], lastIC: { left: null, right: null }, strideTime: { left: 1.1, right: 1.1 },
  cycles: { left: null, right: null }, spatial: { left: null, right: null }, strideCount: { left: 0, right: 0 }, cues: new Map(),
  activity: null, diagnostics: [], icCount: 0, tcPercent: { left: 60, right: 60 },
};
let ws = null;
let dirty = true;

// ---------------------------------------------------------------------------------------------- socket
function connect() {
  // the session token of the link the node logged (…/?token=…) lets this page send commands
  const token = new URLSearchParams(location.search).get("token");
  const url = (location.protocol === "https:" ? "wss://" : "ws://") + location.host + "/ws" +
    (token ? "?token=" + encodeURIComponent(token) : "");
  ws = new WebSocket(url);
  ws.onopen = () => { state.connected = true; setBadge(true); };
  ws.onclose = () => {
    const was = state.connected;
    state.connected = false; setBadge(false);
    if (was && !state.ended) showSessionState("lost");
    setTimeout(connect, state.ended ? 3000 : 1000);
  };
  ws.onmessage = (ev) => { try { handle(JSON.parse(ev.data)); } catch (e) { console.error(e); } };
}

function send(obj) {
  if (ws && ws.readyState === WebSocket.OPEN) { ws.send(JSON.stringify(obj)); return true; }
  showReply({ action: obj.action, success: false, message: "not connected to the biofeedback node" });
  return false;
}

function setBadge(on) {
  const b = document.getElementById("connection");
  b.textContent = on ? "live" : (state.ended ? "session ended" : "disconnected");
  b.className = "badge " + (on ? "on" : "off");
}

// The graph stopped (an "end" message) or the connection broke: the page keeps the last values and says so.
function showSessionState(kind, msg) {
  const el = document.getElementById("session-state");
  const clock = new Date((msg && msg.wall ? msg.wall * 1000 : Date.now())).toLocaleTimeString();
  if (kind === "ended") {
    state.ended = true;
    const t = msg && msg.t !== null && msg.t !== undefined ? " (recording time " + msg.t.toFixed(1) + " s)" : "";
    el.textContent = "Session ended at " + clock + t + ": the last values stay on screen.";
    el.className = "ended";
    for (const c of document.querySelectorAll(".controls button, .controls select")) c.disabled = true;
  } else if (kind === "lost") {
    state.connectionLost = true;
    el.textContent = "Connection to the session lost at " + clock +
      ": the values below are the last received; reconnecting…";
    el.className = "";
  }
  el.hidden = !kind;
  setBadge(state.connected);
}

function handle(msg) {
  if (msg.type === "hello") return onHello(msg);
  if (msg.type === "error") return showReply({ action: "?", success: false, message: msg.message });
  if (msg.type === "end") { showSessionState("ended", msg); dirty = true; return; }
  if (msg.type !== "frame") return;
  state.framesReceived += 1;
  state.lastFrameWall = msg.wall;
  if (msg.samples) {
    for (const row of msg.samples) data.samples.push(row);
    if (data.samples.length > SAMPLES_KEPT) data.samples.splice(0, data.samples.length - SAMPLES_KEPT);
    state.samplesReceived += msg.samples.length;
  }
  if (msg.angles) { data.angles = msg.angles; state.lastAngleStamp = msg.angles.t; }
  if (msg.figure) onFigure(msg.figure);
  for (const m of msg.messages || []) onMessage(m);
  if (msg.activity) data.activity = msg.activity;
  if ("calibration" in msg) showCalibrationInForce(msg.calibration);
  if (msg.diagnostics) data.diagnostics = msg.diagnostics;
  dirty = true;
}

function onHello(msg) {
  if (state.ended) {  // a new session on this port: start from a clean page
    data.cues.clear(); data.spatial = { left: null, right: null }; data.cycles = { left: null, right: null };
    data.strideCount = { left: 0, right: 0 }; data.events = []; data.samples = []; data.figure = null;
    data.angles = null; data.icCount = 0; data.activity = null;
    state.instruction = null; document.getElementById("instruction").hidden = true;
  }
  state.ended = false; state.connectionLost = false;
  showSessionState(null);
  state.hello = true;
  setReadOnly(msg.read_only);
  showCalibrationInForce(msg.calibration);
  data.targets = msg.targets;
  state.feedback = msg.feedback;
  document.getElementById("side").value = msg.feedback.side;
  document.getElementById("joint").value = msg.feedback.joint;
  setMuted(msg.muted, false);
  data.strides = { left: [], right: [] };
  for (const s of msg.strides || []) addStride(s);
  if (msg.audio) state.audio = msg.audio;
  state.coaching = msg.coaching || null;
  if (msg.instruction) showInstruction(msg.instruction, false);
  const src = (msg.targets.reference_sources || []).join(" · ");
  document.getElementById("sources").textContent = src ?
    "Reference curves: textbook key values of normal adult gait (" + src + "); band = reference ± tolerance set in config/targets.yaml, not a published SD." : "";
  dirty = true;
}

function setReadOnly(readOnly) {
  state.readOnly = !!readOnly;
  for (const el of document.querySelectorAll(".controls button, .controls select")) el.disabled = state.readOnly;
  document.getElementById("read-only").hidden = !state.readOnly;
}

function showCalibrationInForce(c) {
  state.calibrationInForce = c || null;
  const el = document.getElementById("calibration-in-force");
  if (!c && state.noLegs) {
    el.textContent = "This kit has no leg or foot sensor: no calibration is needed, and there are no gait or " +
      "joint-angle values to feed back (activity only: posture, transitions, steps).";
    el.className = "ok";
    return;
  }
  if (!c) {
    el.textContent = "Not calibrated yet: no feedback. Stand still, do the calibration moves, then press Calibrate.";
    el.className = "fail";
    return;
  }
  const from = c.in_force_from > 0 ? " from t = " + c.in_force_from.toFixed(1) + " s" : "";
  el.textContent = "In force: " + c.protocol.replace("_", " ") + " calibration, " + c.source + from + " (" +
    c.valid.length + " of " + c.segments + " segments).";
  el.className = c.valid.length === c.segments ? "ok" : "pending";
}

function onFigure(fig) {
  if (data.figure) {
    let d = 0;
    for (let i = 0; i < Math.min(fig.length, data.figure.length); i++) {
      d += Math.abs(fig[i][3] - data.figure[i][3]) + Math.abs(fig[i][4] - data.figure[i][4]);
    }
    state.figureMotion += d;
  }
  data.figure = fig;
  state.figureUpdates += 1;
}

function onMessage(m) {
  switch (m.type) {
    case "event":
      data.events.push(m); state.events += 1;
      if (data.events.length > 200) data.events.splice(0, data.events.length - 200);
      if (m.kind === "IC") { data.lastIC[m.side] = m.t; data.icCount += 1; }
      break;
    case "cycle":
      data.cycles[m.side] = m;
      if (m.plausible && m.stride_time) data.strideTime[m.side] = m.stride_time;
      data.strideCount[m.side] += 1;
      break;
    case "stride": addStride(m); break;
    case "spatial": data.spatial[m.side] = m; break;
    case "cue": data.cues.set(m.quantity + "|" + m.side, m); state.cuesReceived += 1; break;
    case "audio": state.audio = m; break;
    case "instruction": state.instructionsReceived += 1; showInstruction(m, true); break;
    case "reply": showReply(m); break;
  }
}

function addStride(s) {
  const list = data.strides[s.side];
  list.push(s);
  if (list.length > STRIDES_KEPT) list.shift();
  data.tcPercent[s.side] = s.tc_percent;
  state.strideCurves += 1;
}

function showReply(m) {
  state.lastReply = m;
  const text = (m.success ? "✔ " : "✖ ") + m.message;
  if (m.action === "calibrate") {
    const el = document.getElementById("calibration-message");
    el.textContent = "Calibration: " + (m.pending ? m.message : text);
    el.className = m.pending ? "pending" : (m.success ? "ok" : "fail");
    if (!m.pending) {
      state.lastCalibration = { success: m.success, message: m.message, segments: m.segments || [],
                                looksLike: m.looks_like || "" };
      document.getElementById("calibrate").disabled = false;
      proposeProtocol(m);
    }
  } else {
    document.getElementById("reply-message").textContent = m.action + ": " + text;
    if (m.action === "record_start" && m.success) document.getElementById("record-start").classList.add("active");
    if (m.action === "record_stop" && m.success) document.getElementById("record-start").classList.remove("active");
    if (m.action === "feedback" && m.feedback) state.feedback = m.feedback;
  }
}

// After a refusal, propose the protocol the movement looked like: select it and say so (never calibrate
// with it unasked: the clinician presses Calibrate again).
function proposeProtocol(m) {
  const select = document.getElementById("protocol");
  const seen = m.looks_like || "";
  if (m.success || !seen || select.value === seen) return;
  select.value = seen;
  state.proposedProtocol = seen;
  const el = document.getElementById("calibration-message");
  el.textContent += " — the movement looks like " + seen.replace("_", " ") +
    ": protocol set to it, press Calibrate to use it.";
}

// ---------------------------------------------------------------------------------------------- controls
function setupControls() {
  document.getElementById("calibrate").addEventListener("click", () => {
    const protocol = document.getElementById("protocol").value;
    if (send({ action: "calibrate", protocol })) {
      document.getElementById("calibrate").disabled = true;
      const el = document.getElementById("calibration-message");
      el.textContent = "Calibration: requested (" + protocol + ") …"; el.className = "pending";
    }
  });
  document.getElementById("record-start").addEventListener("click", () => send({ action: "record_start" }));
  document.getElementById("record-stop").addEventListener("click", () => send({ action: "record_stop" }));
  const feedback = () => {
    state.feedback = { side: document.getElementById("side").value, joint: document.getElementById("joint").value };
    send({ action: "feedback", side: state.feedback.side, joint: state.feedback.joint });
    dirty = true;
  };
  document.getElementById("side").addEventListener("change", feedback);
  document.getElementById("joint").addEventListener("change", feedback);
  document.getElementById("mute").addEventListener("click", () => { setMuted(!state.muted, true); });
  // the browser allows sound only after a user gesture
  document.addEventListener("click", () => { audio.resume(); }, { capture: true });
}

function setMuted(muted, tell) {
  state.muted = muted;
  if (muted && window.speechSynthesis) window.speechSynthesis.cancel();
  document.getElementById("mute").textContent = muted ? "Sound: muted" : "Sound: on";
  if (tell) send({ action: "mute", muted });
}

// ---------------------------------------------------------------------------------------------- audio
// Beeps of the cue the node selected: pitch and rate follow the error (thesis ch. 8); silent in band.
const audio = {
  ctx: null, nextBeep: 0,
  resume() {
    if (!this.ctx) {
      const AC = window.AudioContext || window.webkitAudioContext;
      if (!AC) return;
      this.ctx = new AC();
    }
    if (this.ctx.state === "suspended") this.ctx.resume();
  },
  tick() {
    const a = state.audio;
    if (!this.ctx || state.ended || state.muted || !a || !(a.rate > 0) || !(a.frequency > 0)) return;
    const now = this.ctx.currentTime;
    if (this.nextBeep < now) this.nextBeep = now + 0.02;
    while (this.nextBeep < now + 0.2) {
      this.beep(this.nextBeep, a.frequency, Math.min(0.09, 0.5 / a.rate));
      this.nextBeep += 1 / a.rate;
    }
  },
  beep(t, f, dur) {
    const osc = this.ctx.createOscillator();
    const gain = this.ctx.createGain();
    osc.frequency.value = f;
    gain.gain.setValueAtTime(0, t);
    gain.gain.linearRampToValueAtTime(0.25, t + 0.005);
    gain.gain.linearRampToValueAtTime(0, t + dur);
    osc.connect(gain).connect(this.ctx.destination);
    osc.start(t); osc.stop(t + dur + 0.01);
  },
};

// ---------------------------------------------------------------------------------------------- instruction
// One instruction at a time (issue 49), as the node's schedule gives it: shown large; its words spoken
// with the browser's speech synthesis, or two short tones where the browser has no voice; muted: shown only.
function showInstruction(m, fresh) {
  state.instruction = m;
  const box = document.getElementById("instruction");
  const q = m.quantity;
  const summary = m.schedule === "summary" ?
    " — " + m.block_in_band + " of " + m.block_strides + " strides in the target range" : "";
  document.getElementById("instruction-text").textContent =
    m.in_band ? m.label + ": in the target range" : m.text;
  document.getElementById("instruction-detail").textContent = m.label + ": measured " +
    fmtQuantity(m.unit, m.measured, q) + ", target " + fmtQuantity(m.unit, m.low, q) + " to " +
    fmtQuantity(m.unit, m.high, q) + summary + " (feedback: " + SCHEDULE_WORDS[m.schedule] + ")";
  box.className = m.in_band ? "in-band" : "";
  box.hidden = false;
  if (fresh && m.kind === "instruction") say(m.text);
}

// Browsers load their voices after the page: asking once at start has them ready for the first words.
if (window.speechSynthesis) window.speechSynthesis.getVoices();

const SCHEDULE_WORDS = { every_stride: "every stride", bandwidth: "only outside the target range",
  faded: "fading over the session", summary: "a summary every few strides" };

function say(text) {
  if (state.muted || state.ended) return;
  const synth = window.speechSynthesis;
  if (synth && window.SpeechSynthesisUtterance && synth.getVoices().length > 0) {
    if (synth.speaking || synth.pending) return;  // the words of the last one are still being said
    const u = new SpeechSynthesisUtterance(text);
    u.lang = "en-GB"; u.rate = 0.95;
    synth.speak(u);
    state.spoken += 1; state.lastSpoken = text;
    return;
  }
  audio.resume();  // no voice: two short tones announce the words on screen
  if (!audio.ctx) return;
  const t = audio.ctx.currentTime + 0.02;
  audio.beep(t, 880, 0.12); audio.beep(t + 0.18, 660, 0.12);
  state.toneFallbacks += 1;
}

// ---------------------------------------------------------------------------------------------- drawing
// A canvas sized to its box (CSS width, height from data-aspect) at the screen's pixel ratio; drawing
// is in CSS pixels, so labels keep their size whatever the window.
function canvas2d(id) {
  const c = document.getElementById(id);
  const dpr = window.devicePixelRatio || 1;
  const w = Math.max(120, c.clientWidth), h = Math.round(w * parseFloat(c.dataset.aspect || "0.5"));
  if (c.width !== Math.round(w * dpr) || c.height !== Math.round(h * dpr)) {
    c.width = Math.round(w * dpr); c.height = Math.round(h * dpr); c.style.height = h + "px";
  }
  const g = c.getContext("2d");
  g.setTransform(dpr, 0, 0, dpr, 0, 0);
  g.clearRect(0, 0, w, h);
  return { c, g, w, h };
}

// An axis label kept inside the canvas: aligned left at the left edge, right at the right edge.
function label(g, text, x, y, w, align) {
  const width = g.measureText(text).width;
  let x0 = align === "center" ? x - width / 2 : align === "right" ? x - width : x;
  x0 = Math.max(1, Math.min(w - width - 1, x0));
  g.textAlign = "left";
  g.fillText(text, x0, y);
  if (x0 < 0 || x0 + width > w) state.clippedLabels += 1;
}

function wrapText(g, text, x, y, maxWidth, lineHeight) {
  let line = "";
  for (const word of text.split(" ")) {
    const next = line ? line + " " + word : word;
    if (g.measureText(next).width > maxWidth && line) { g.fillText(line, x, y); y += lineHeight; line = word; }
    else line = next;
  }
  if (line) g.fillText(line, x, y);
}

function drawFigure() {
  const { g, w, h } = canvas2d("figure");
  const scale = h / 1.45, ox = w * 0.5, oy = h * 0.1;  // the ground above the two lines of angles
  g.strokeStyle = "#ccc"; g.lineWidth = 1;
  g.beginPath(); g.moveTo(0, oy + 0.98 * scale); g.lineTo(w, oy + 0.98 * scale); g.stroke();
  if (!data.figure) {
    g.fillStyle = "#666"; g.font = "14px sans-serif";
    const c = state.calibrationInForce;
    const legs = !c || c.valid.some((seg) => seg.endsWith("_thigh") || seg.endsWith("_shank"));
    wrapText(g, state.noLegs ? "No joint angles with this kit: it has no leg sensor." :
      !calibrated() ? "The stick figure appears once a calibration is in force (joint angles need it)." :
      legs ? "waiting for joint angles" : "No joint angles with this kit: every joint needs a thigh or shank " +
      "sensor, and the calibrated ones are " + c.valid.join(", ").replace(/_/g, " ") + ".", 16, h / 2 - 20, w - 32, 20);
    return;
  }
  // far (left) leg first, then pelvis, then the near (right) leg
  const order = (seg) => (seg.startsWith("left") ? 0 : seg === "pelvis" ? 1 : 2);
  const segs = data.figure.slice().sort((a, b) => order(a[0]) - order(b[0]));
  g.lineCap = "round";
  for (const [seg, x0, y0, x1, y1] of segs) {
    const side = seg.startsWith("left") ? "left" : seg.startsWith("right") ? "right" : "pelvis";
    g.strokeStyle = COLORS[side];
    g.lineWidth = seg === "pelvis" ? 10 : seg.endsWith("foot") ? 6 : 8;
    g.globalAlpha = side === "left" ? 0.8 : 1;
    g.beginPath(); g.moveTo(ox + x0 * scale, oy - y0 * scale); g.lineTo(ox + x1 * scale, oy - y1 * scale); g.stroke();
    g.fillStyle = "#1d2430";
    g.beginPath(); g.arc(ox + x1 * scale, oy - y1 * scale, 3.5, 0, 2 * Math.PI); g.fill();
  }
  g.globalAlpha = 1;
  if (!segs.some((s) => s[0] !== "pelvis")) {
    g.fillStyle = "#666"; g.font = "14px sans-serif";
    wrapText(g, "No leg angles at this instant (a sensor is missing or recovering).", 16, h / 2, w - 32, 20);
  }
  // angle read-out
  const v = data.angles ? data.angles.values : {};
  g.font = "12px sans-serif";
  SIDES.forEach((side, k) => {
    g.fillStyle = COLORS[side];
    const txt = CURVES.map((n) => {
      const a = v[side + "_" + n];
      return n.split("_")[0] + " " + (a === undefined ? "–" : (a * DEG).toFixed(0) + "°");
    }).join("  ");
    label(g, side + ": " + txt, 8, h - 24 + 15 * k, w, "left");
  });
  const recovering = data.angles && data.angles.recovering && data.angles.recovering.length
    ? "  — sensor dropout, recovering: " + data.angles.recovering.join(", ") + " (no feedback)" : "";
  document.getElementById("figure-time").textContent =
    data.angles ? "t = " + data.angles.t.toFixed(2) + " s" + recovering : "";
}

function drawEvents() {
  const { g, w, h } = canvas2d("events");
  const tNow = data.angles ? data.angles.t : (data.events.length ? data.events[data.events.length - 1].t : 0);
  const x = (t) => w - 10 - (tNow - t) / EVENT_WINDOW * (w - 50);
  g.font = "11px sans-serif";
  SIDES.forEach((side, k) => {
    const y = h * (0.3 + 0.4 * k);
    g.fillStyle = COLORS[side]; g.fillText(side[0].toUpperCase(), 6, y + 4);
    g.strokeStyle = "#ddd"; g.beginPath(); g.moveTo(30, y); g.lineTo(w - 5, y); g.stroke();
    for (const e of data.events) {
      if (e.side !== side || tNow - e.t > EVENT_WINDOW || e.t > tNow + 0.5) continue;
      const px = x(e.t);
      g.beginPath();
      if (e.kind === "IC") { g.moveTo(px, y - 8); g.lineTo(px - 5, y + 6); g.lineTo(px + 5, y + 6); g.closePath(); g.fillStyle = COLORS[side]; g.fill(); }
      else { g.moveTo(px, y + 8); g.lineTo(px - 5, y - 6); g.lineTo(px + 5, y - 6); g.closePath(); g.strokeStyle = COLORS[side]; g.lineWidth = 1.5; g.stroke(); g.lineWidth = 1; }
    }
  });
}

function chosenSides() { return state.feedback.side === "both" ? SIDES : [state.feedback.side]; }

function drawCurve(name) {
  const { g, w, h } = canvas2d("curve-" + name);
  const [lo, hi] = CURVE_RANGE[name];
  const L = 34, R = 6, T = 18, B = 16, W = w - L - R, H = h - T - B;
  const px = (p) => L + p / 100 * W;
  const py = (deg) => T + (hi - Math.max(lo, Math.min(hi, deg))) / (hi - lo) * H;
  // axes
  g.strokeStyle = "#e3e3e3"; g.fillStyle = "#666"; g.font = "11px sans-serif"; g.lineWidth = 1;
  for (let d = Math.ceil(lo / 15) * 15; d <= hi; d += 15) {
    g.beginPath(); g.moveTo(L, py(d)); g.lineTo(L + W, py(d)); g.stroke();
    label(g, d + "°", L - 4, py(d) + 4, w, "right");
  }
  for (let p = 0; p <= 100; p += 20) label(g, p + " %", px(p), h - 3, w, p === 0 ? "left" : p === 100 ? "right" : "center");
  g.fillStyle = "#1d2430"; g.font = "bold 12px sans-serif";
  label(g, CURVE_TITLES[name] + " (" + chosenSides().join(" + ") + ")", L + 4, 13, w, "left");
  // reference band
  const ref = data.targets && data.targets.reference ? data.targets.reference[name] : null;
  if (ref) {
    g.fillStyle = "rgba(42,157,75,0.16)";
    g.beginPath();
    ref.percent.forEach((p, i) => { const f = i ? g.lineTo : g.moveTo; f.call(g, px(p), py(ref.high[i] * DEG)); });
    for (let i = ref.percent.length - 1; i >= 0; i--) g.lineTo(px(ref.percent[i]), py(ref.low[i] * DEG));
    g.closePath(); g.fill();
    g.strokeStyle = "rgba(42,157,75,0.7)"; g.setLineDash([4, 3]); g.beginPath();
    ref.percent.forEach((p, i) => { const f = i ? g.lineTo : g.moveTo; f.call(g, px(p), py(ref.mean[i] * DEG)); });
    g.stroke(); g.setLineDash([]);
  }
  let points = 0;
  for (const side of chosenSides()) {
    // completed strides: older ones fainter
    const list = data.strides[side];
    list.forEach((s, k) => {
      const ys = s.curves[name];
      if (!ys) return;
      g.strokeStyle = COLORS[side]; g.globalAlpha = 0.15 + 0.45 * (k + 1) / list.length; g.lineWidth = 1.2;
      g.beginPath();
      s.percent.forEach((p, i) => { const f = i ? g.lineTo : g.moveTo; f.call(g, px(p), py(ys[i] * DEG)); });
      g.stroke();
      points += ys.length;
    });
    g.globalAlpha = 1;
    // toe-off marker of the latest stride
    const tc = data.tcPercent[side];
    g.strokeStyle = COLORS[side]; g.setLineDash([2, 3]);
    g.beginPath(); g.moveTo(px(tc), T); g.lineTo(px(tc), T + H); g.stroke(); g.setLineDash([]);
    g.fillStyle = COLORS[side]; g.font = "10px sans-serif";
    label(g, "toe off", px(tc) + 2, T + 9 + (side === "right" ? 10 : 0), w, "left");
    // live stride since the last heel strike of this side
    const t0 = data.lastIC[side];
    if (t0 !== null && !state.ended) {
      const col = 1 + SIDES.indexOf(side) * 3 + CURVES.indexOf(name);
      const Ts = data.strideTime[side];
      g.strokeStyle = COLORS[side]; g.lineWidth = 2.6; g.beginPath();
      let first = true;
      for (const row of data.samples) {
        if (row[0] < t0 || row[col] === null) continue;
        const p = (row[0] - t0) / Ts * 100;
        if (p > 110) continue;
        if (first) { g.moveTo(px(p), py(row[col] * DEG)); first = false; } else g.lineTo(px(p), py(row[col] * DEG));
        points += 1;
      }
      g.stroke(); g.lineWidth = 1;
    }
  }
  // heel strike at 0 %
  g.strokeStyle = "#333"; g.beginPath(); g.moveTo(px(0), T); g.lineTo(px(0), T + H); g.stroke();
  g.fillStyle = "#333"; g.font = "10px sans-serif"; label(g, "heel strike", px(0) + 2, T + H - 3, w, "left");
  return points;
}

function fmtQuantity(unit, v, quantity) {
  if (v === null || v === undefined) return "–";
  if (unit === "rad") return (v * DEG).toFixed(1) + "°";
  if (quantity === "cadence") return (v * 60).toFixed(0) + " steps/min";
  if (unit === "1") return (v * 100).toFixed(1) + " %";
  return v.toFixed(2) + " " + unit;
}

// ---------------------------------------------------------------------------------------------- values
// One source for every value shown: the latest evaluated stride of each side ("spatial" messages, with
// every quantity in .values). The Gait panel and the Targets table both read it through valueOf.
const BILATERAL = new Set(["cadence", "step_time_symmetry", "gait_speed", "step_length_symmetry",
  "step_length_asymmetry_paretic", "stance_time_asymmetry_paretic"]);
const UNITS = { stance_fraction: "1", step_time_symmetry: "1", cadence: "Hz", stride_length: "m", gait_speed: "m/s",
  step_length: "m", step_length_symmetry: "1" };

function latestRecord(quantity, side) {
  if (!BILATERAL.has(quantity)) return data.spatial[side] || null;
  return [data.spatial.left, data.spatial.right].filter(Boolean).sort((a, b) => b.t - a.t)[0] || null;
}

function valueOf(quantity, side) {
  const r = latestRecord(quantity, side);
  if (!r || !r.values) return null;
  const v = r.values[quantity];
  return v === undefined ? null : v;
}

function shown(quantity, side) { return fmtQuantity(UNITS[quantity], valueOf(quantity, side), quantity); }

// Why the latest stride has no value of a quantity (a clinician's words).
function whyNone(r) {
  if (!r) return "no stride yet";
  if (r.flag) return "latest stride doubtful: " + r.flag;
  if (r.turning) return "latest stride turning";
  return "no value from the latest stride";
}

function calibrated() {
  const c = state.calibrationInForce;
  return !!(c && c.valid && c.valid.length);
}

function renderProgress() {
  const box = document.getElementById("calibration-progress");
  const d = data.diagnostics.find((x) => x.name === PROGRESS_STATUS);
  if (!d) { box.hidden = true; state.calibrationProgress = ""; return; }
  box.hidden = false;
  const v = d.values, need = parseFloat(v.standing_needed_s), s = parseFloat(v.standing_s);
  const done = v.standing_done === "true";
  document.getElementById("progress-standing").textContent = done && s < need ? "Standing still: done" :
    "Standing still: " + Math.min(s, need).toFixed(1) + " of " + need + " s";
  document.getElementById("progress-standing-bar").style.width = (done ? 100 : Math.min(100, s / need * 100)) + "%";
  const counts = SIDES.filter((side) => v[side + "_cycles"] !== "" && v[side + "_cycles"] !== undefined)
    .map((side) => side + " " + v[side + "_cycles"]);
  const noLegs = done && !counts.length;  // a trunk-only kit: nothing to calibrate
  if (noLegs !== !!state.noLegs) { state.noLegs = noLegs; showCalibrationInForce(state.calibrationInForce); }
  box.hidden = noLegs;
  document.getElementById("progress-moves").textContent = done ?
    "Moves since the standing: " + (counts.join(", ") || "no leg sensor") + " (hip flexion: " +
    v.hip_flexion_cycles_needed + " per leg; walking: " + v.walking_swings_needed + " steps per leg)" :
    "Moves: counted once the standing is done";
  state.calibrationProgress = box.textContent.replace(/\s+/g, " ").trim();
}

function updateAudio() {
  const el = document.getElementById("audio-state");
  const s = state.audio;
  const mute = state.muted ? " (sound off)" : "";
  if (state.ended) { el.textContent = "session ended: no sound"; el.removeAttribute("title"); return; }
  if (!calibrated()) {
    el.textContent = state.noLegs ? "no feedback: this kit measures activity only" : "not calibrated yet: no feedback";
    el.removeAttribute("title"); return;
  }
  if (!s || !(s.rate > 0)) {
    el.textContent = (data.cues.size ? "in the target range: no sound" : "no stride evaluated yet: no sound") + mute;
    el.removeAttribute("title"); return;
  }
  const unit = s.unit, q = s.quantity;
  el.textContent = (s.advice || s.label || q) + mute + " — target " + fmtQuantity(unit, s.low, q) + " to " +
    fmtQuantity(unit, s.high, q) + ", measured " + fmtQuantity(unit, s.measured, q);
  el.title = "Tone: " + s.frequency.toFixed(0) + " Hz, " + s.rate.toFixed(1) +
    " beeps/s (higher pitch: too much; lower pitch: too little; faster beeps: further off)";
}

function updateTables() {
  const sl = data.spatial.left, sr = data.spatial.right;
  const newest = [sl, sr].filter(Boolean).sort((a, b) => b.t - a.t)[0];
  const set = (id, text) => { document.getElementById(id).textContent = text; };
  // the gait parameters of the latest stride (of each side, or the newest for bilateral ones)
  set("stat-cadence", shown("cadence", ""));
  set("stat-stance", shown("stance_fraction", "left") + " / " + shown("stance_fraction", "right"));
  set("stat-symmetry", shown("step_time_symmetry", ""));
  set("stat-speed", shown("gait_speed", ""));
  set("stat-stride-length", shown("stride_length", "left") + " / " + shown("stride_length", "right"));
  set("stat-step-length", shown("step_length", "left") + " / " + shown("step_length", "right"));
  set("stat-step-symmetry", shown("step_length_symmetry", ""));
  const cm = (s) => (s && s.max_foot_height !== null && s.max_foot_height !== undefined ?
    (s.max_foot_height * 100).toFixed(1) + " cm" : "–");
  const deg = (s) => (s && s.foot_angle_ic !== null && s.foot_angle_ic !== undefined ?
    (s.foot_angle_ic * DEG).toFixed(0) + "°" : "–");
  set("stat-foot-height", cm(sl) + " / " + cm(sr));
  set("stat-foot-angle", deg(sl) + " / " + deg(sr));
  const turn = (s) => (s.turning_angle !== null && s.turning_angle !== undefined ?
    "turning " + Math.abs(s.turning_angle * DEG).toFixed(0) + "°" : "turn not known yet") + ": no spatial cue";
  set("stat-spatial-flag", !newest ? "–" :
    (newest.flag ? newest.side + ": " + newest.flag : (newest.turning ? newest.side + ": " + turn(newest) : "ok")));
  const steps = data.activity ? data.activity.step_count : data.icCount;
  set("stat-steps", String(steps));
  set("stat-strides", data.strideCount.left + " / " + data.strideCount.right);
  // activity
  const a = data.activity;
  set("activity", a ? a.posture + (a.locomotion !== "none" ? ", " + a.locomotion : "") + " · trunk " +
    (a.trunk_inclination * DEG).toFixed(0) + "° · last transition: " + a.last_transition : "no activity monitor data");
  updateAudio();
  renderProgress();
  // cues: a row is the latest stride's only when the cue came from that stride (else its value is "–")
  const body = document.querySelector("#cues tbody");
  const rows = [...data.cues.values()].sort((x, y) => (x.quantity + x.side).localeCompare(y.quantity + y.side));
  const groups = { knee_flexion_peak_swing: "knee", knee_flexion_at_ic: "knee", hip_extension_peak_stance: "hip",
    ankle_dorsiflexion_at_ic: "ankle", stance_fraction: "timing", step_time_symmetry: "timing", cadence: "timing",
    stride_length: "spatial", gait_speed: "spatial", step_length: "spatial", step_length_symmetry: "spatial",
    trailing_limb_angle: "hip", propulsion: "ankle", knee_hyperextension_stance: "knee", foot_strike_angle: "ankle",
    swing_foot_clearance: "spatial", step_length_asymmetry_paretic: "spatial", stance_time_asymmetry_paretic: "timing" };
  body.textContent = "";
  for (const c of rows) {
    const record = latestRecord(c.quantity, c.side);
    const current = record && record.side === c.stride_side && record.stride === c.stride;
    const chosen = (state.feedback.side === "both" || c.side === "" || c.side === state.feedback.side) &&
      (state.feedback.joint === "all" || groups[c.quantity] === state.feedback.joint);
    const tr = document.createElement("tr");
    tr.className = (current ? "sev" + c.severity : "") + (chosen && current ? "" : " dim");
    const span = (c.high - c.low) || 1, lo = c.low - span, hi = c.high + span;
    const pos = (v) => Math.max(0, Math.min(100, (v - lo) / (hi - lo) * 100));
    const cells = [c.label || c.quantity, current ? fmtQuantity(c.unit, c.measured, c.quantity) : "–",
      fmtQuantity(c.unit, c.low, c.quantity) + " to " + fmtQuantity(c.unit, c.high, c.quantity), null,
      current ? (c.advice || "") : whyNone(record)];
    cells.forEach((text, i) => {
      const td = document.createElement("td");
      if (i === 4) td.className = "cue";
      if (text === null) {
        const bar = document.createElement("div"); bar.className = "bar";
        const band = document.createElement("div"); band.className = "band";
        band.style.left = pos(c.low) + "%"; band.style.width = (pos(c.high) - pos(c.low)) + "%";
        bar.appendChild(band);
        if (current && c.measured !== null) {
          const dot = document.createElement("div"); dot.className = "dot"; dot.style.left = pos(c.measured) + "%";
          bar.appendChild(dot);
        }
        td.appendChild(bar);
      } else td.textContent = text;
      tr.appendChild(td);
    });
    body.appendChild(tr);
  }
  // diagnostics (the calibration progress has its own view)
  const dbody = document.querySelector("#diagnostics tbody");
  dbody.textContent = "";
  const names = ["OK", "WARN", "ERROR", "STALE"];
  const interesting = /rate|drop|gap|batter|missing|stale|hz|latency|published/i;
  for (const d of [...data.diagnostics].sort((x, y) => x.name.localeCompare(y.name))) {
    if (d.name === PROGRESS_STATUS) continue;
    const vals = Object.entries(d.values).filter(([k]) => interesting.test(k)).slice(0, 4)
      .map(([k, v]) => k + " " + v).join(", ");
    const tr = document.createElement("tr");
    const level = document.createElement("td"); level.className = "lvl" + d.level; level.textContent = names[d.level] || d.level;
    const name = document.createElement("td"); name.textContent = d.name;
    const text = document.createElement("td"); text.textContent = d.message;
    if (vals) { const small = document.createElement("small"); small.textContent = vals; text.appendChild(document.createElement("br")); text.appendChild(small); }
    tr.append(level, name, text);
    dbody.appendChild(tr);
  }
}

// ---------------------------------------------------------------------------------------------- loop
let lastTables = 0, fpsCount = 0, fpsStart = performance.now();
function render() {
  const now = performance.now();
  audio.tick();
  drawFigure();
  drawEvents();
  let points = 0;
  for (const name of CURVES) points += drawCurve(name);
  state.curvePoints = points;
  state.clippedLabelsNow = state.clippedLabels; state.clippedLabels = 0;
  if (dirty && now - lastTables > 200) { updateTables(); lastTables = now; dirty = false; }
  state.framesRendered += 1;
  fpsCount += 1;
  if (now - fpsStart > 1000) { state.fps = fpsCount * 1000 / (now - fpsStart); fpsCount = 0; fpsStart = now; }
}

function loop() { render(); requestAnimationFrame(loop); }

setupControls();
connect();
requestAnimationFrame(loop);
