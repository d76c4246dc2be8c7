/*
 * efdm-tracker demo page: choose a source (video file, camera, or the synthetic
 * scene of ?demo=synthetic), draw an outline around each object (a box, a
 * circle or a polygon), then stream JPEG frames over the WebSocket of a new
 * session of several objects and draw each tracked contour in its own colour.
 * Outlines drawn while tracking are added to the session mid-stream.
 *
 * Coordinates sent to and received from the server are video pixels [x, y]
 * (x = column, y = row) of the source's intrinsic size; the overlay canvas has
 * that size too, so it draws in the same coordinates and CSS scales it.
 *
 * State for tests and the curious: window.efdmDemo (see `demo` below).
 */
"use strict";

(() => {
  const $ = (id) => document.getElementById(id);
  const ui = {
    file: $("file"),
    camera: $("camera"),
    closePolygon: $("close-polygon"),
    clear: $("clear"),
    apiKey: $("api-key"),
    snap: $("snap"),
    objectList: $("object-list"),
    track: $("track"),
    stop: $("stop"),
    stage: $("stage"),
    video: $("video"),
    synthetic: $("synthetic"),
    overlay: $("overlay"),
    placeholder: $("placeholder"),
    status: $("status"),
    error: $("error"),
    fps: $("stat-fps"),
    latency: $("stat-latency"),
    dropped: $("stat-dropped"),
    confidence: $("stat-confidence"),
    frame: $("stat-frame"),
  };

  const params = new URLSearchParams(location.search);
  const clamp = (v, lo, hi) => Math.min(hi, Math.max(lo, v));
  // Frames sent but not yet answered (or reported dropped); ?inflight=N overrides.
  const MAX_IN_FLIGHT = clamp(parseInt(params.get("inflight") || "2", 10) || 2, 1, 8);
  const JPEG_QUALITY = 0.8;
  const CIRCLE_NODES = 64;
  const MAX_OBJECTS = 32; // the server's limit per session
  const MIN_OUTLINE_PX = 3; // a box narrower, or a circle's radius smaller, is a slip
  // One colour per object, in the order they were drawn; the first is the page's green.
  const PALETTE = [
    "#39ff7a", "#4dc3ff", "#ff5ca8", "#ffb000",
    "#b388ff", "#00e5d4", "#ff6b6b", "#c6ff00",
  ];
  // A demo session expires after two idle minutes (the page also deletes it when closed).
  const SESSION_TTL_SECONDS = 120;
  const DRAG_PX = 5; // CSS pixels a press must move to become a circle drag
  const FPS_WINDOW_MS = 2000;

  // Public, read-only state (the end-to-end test polls it).
  const demo = {
    source: null, // "file" | "camera" | "synthetic"
    sessionId: null,
    tracking: false,
    sent: 0, // frames sent on the current stream
    results: 0, // frame results received
    dropped: 0, // sum of the results' "dropped"
    lastNodes: null, // [[x, y], ...] of the latest result (its first object)
    lastObjects: null, // [{id, nodes | contours, status, confidence, behind}, ...], latest result
    outlines: 0, // outlines drawn, not yet tracked
    pendingObjects: 0, // objects sent mid-stream, not yet acknowledged
    lastResult: null,
    latencyMs: null,
    lastError: null, // {status, code, message} or a client-side message
    closed: null, // {code, reason} of the last socket close
    disc: null, // synthetic scene: the disc now, {x, y, r}
    lastResultDisc: null, // synthetic scene: the disc in the frame of lastNodes
    lastResultTime: null, // video file: currentTime (s) of the frame of lastNodes
  };
  window.efdmDemo = demo;

  let source = null; // {kind, el, width, height, fresh(), taken(), stop(), render?, disc?}
  // An outline: {kind: "polygon", points} | {kind: "circle", center, radius}
  // | {kind: "box", from, to} (two opposite corners)
  let outlines = []; // drawn, to be tracked when Track is pressed
  let draft = null; // being drawn: an open polygon, or the box or circle being dragged
  let pending = []; // outlines sent to the session mid-stream, not yet acknowledged
  // Control messages sent, in order, awaiting their answer: "add" (its outline is in
  // `pending`) or "remove"; the server answers them in the order they were sent.
  let controls = [];
  const colours = new Map(); // object id -> colour
  let press = null; // pointer press on the overlay (click or circle drag)
  let session = null; // {id, key}
  let socket = null;
  let stopping = false; // the user pressed Stop (a close is expected)
  let inflight = []; // [{sentAt, disc, time}] in send order
  let encoding = false;
  let tick = 0; // animation frames so far: at most one capture per frame
  let lastCaptureTick = -1;
  let resultTimes = [];
  let trackingSince = 0;
  let latencyAvg = null;
  let lastStatsPaint = 0;
  const capture = document.createElement("canvas"); // offscreen, intrinsic size
  const captureCtx = capture.getContext("2d");
  const overlayCtx = ui.overlay.getContext("2d");

  // ---------------------------------------------------------------- messages

  function setStatus(text) {
    ui.status.textContent = text;
  }

  function showError(text, detail = null) {
    ui.error.textContent = text;
    ui.error.hidden = false;
    demo.lastError = detail || { message: text };
  }

  function clearError() {
    ui.error.hidden = true;
    ui.error.textContent = "";
    demo.lastError = null;
  }

  // ----------------------------------------------------------------- sources

  /** Use `next` as the picture source: show it, size the overlay, reset the contour. */
  function setSource(next) {
    source = next;
    demo.source = next.kind;
    ui.placeholder.hidden = true;
    next.el.hidden = false;
    forgetOutlines();
    demo.lastNodes = null;
    layout();
    updateButtons();
  }

  /** Stop and hide the current source (before the next one touches the <video>). */
  function releaseSource() {
    if (!source) return;
    source.stop();
    source.el.hidden = true;
    source = null;
    demo.source = null;
    forgetOutlines();
    ui.placeholder.hidden = false;
    updateButtons();
  }

  /**
   * A <video> source (file or camera). A picture is fresh when the video has
   * presented a new frame since the last capture: requestVideoFrameCallback
   * where the browser has it, else a change of currentTime (camera: always).
   */
  function videoSource(kind, video, release) {
    const rvfc = typeof video.requestVideoFrameCallback === "function";
    let presented = 0;
    let captured = -1;
    let capturedTime = -1;
    let handle = null;
    const onFrame = () => {
      presented += 1;
      handle = video.requestVideoFrameCallback(onFrame);
    };
    if (rvfc) handle = video.requestVideoFrameCallback(onFrame);
    return {
      kind,
      el: video,
      get width() { return video.videoWidth; },
      get height() { return video.videoHeight; },
      fresh() {
        if (video.ended) return false;
        if (rvfc) return presented !== captured;
        return kind === "camera" || video.currentTime !== capturedTime;
      },
      taken() {
        captured = presented;
        capturedTime = video.currentTime;
      },
      stop() {
        if (rvfc && handle !== null) video.cancelVideoFrameCallback(handle);
        release();
      },
    };
  }

  function useVideoFile(file) {
    releaseSource();
    const video = ui.video;
    const url = URL.createObjectURL(file);
    video.srcObject = null;
    video.loop = false;
    video.src = url;
    setStatus(`Loading ${file.name}…`);
    video.addEventListener(
      "loadeddata",
      () => {
        video.pause();
        setSource(
          videoSource("file", video, () => {
            video.pause();
            video.removeAttribute("src");
            video.load();
            URL.revokeObjectURL(url);
          }),
        );
        setStatus(`${file.name}: ${video.videoWidth}×${video.videoHeight}. Outline the objects.`);
      },
      { once: true },
    );
  }

  async function useCamera() {
    if (!navigator.mediaDevices || !navigator.mediaDevices.getUserMedia) {
      showError(
        window.isSecureContext
          ? "This browser gives no camera access."
          : "The camera needs a secure page (https:// or http://localhost).",
      );
      return;
    }
    let stream;
    try {
      stream = await navigator.mediaDevices.getUserMedia({
        video: { width: { ideal: 640 }, height: { ideal: 480 } },
        audio: false,
      });
    } catch (err) {
      const why = {
        NotAllowedError: "permission was denied",
        SecurityError: "permission was denied",
        NotFoundError: "no camera was found",
        OverconstrainedError: "no camera fits",
        NotReadableError: "the camera is busy",
      }[err.name] || err.message;
      showError(`Cannot use the camera: ${why}.`);
      return;
    }
    releaseSource();
    const video = ui.video;
    video.removeAttribute("src");
    video.srcObject = stream;
    try {
      await video.play();
    } catch (err) {
      stream.getTracks().forEach((t) => t.stop());
      showError(`Cannot play the camera: ${err.message}`);
      return;
    }
    clearError();
    setSource(
      videoSource("camera", video, () => {
        stream.getTracks().forEach((t) => t.stop());
        video.srcObject = null;
      }),
    );
    setStatus(`Camera: ${video.videoWidth}×${video.videoHeight}. Outline the objects.`);
  }

  /**
   * ?demo=synthetic: a red disc on a light textured background, drawn with
   * canvas 2D. It stands still until tracking starts, then wanders smoothly.
   */
  function makeSynthetic() {
    const W = 512;
    const H = 320;
    const R = 44;
    const canvas = ui.synthetic;
    canvas.width = W;
    canvas.height = H;
    const ctx = canvas.getContext("2d");

    // Background: seeded noise at 1/4 resolution, scaled up smoothly (soft blotches).
    const small = document.createElement("canvas");
    small.width = W / 4;
    small.height = H / 4;
    const sctx = small.getContext("2d");
    const img = sctx.createImageData(small.width, small.height);
    let seed = 12345;
    const rand = () => ((seed = (seed * 1103515245 + 12345) >>> 0) / 4294967296);
    for (let i = 0; i < img.data.length; i += 4) {
      const g = 185 + rand() * 45;
      img.data[i] = g;
      img.data[i + 1] = g - 4;
      img.data[i + 2] = g - 12;
      img.data[i + 3] = 255;
    }
    sctx.putImageData(img, 0, 0);
    const background = document.createElement("canvas");
    background.width = W;
    background.height = H;
    const bctx = background.getContext("2d");
    bctx.imageSmoothingEnabled = true;
    bctx.filter = "blur(3px)"; // ignored where unsupported: then the blotches are just sharper
    bctx.drawImage(small, -8, -8, W + 16, H + 16);
    bctx.filter = "none";

    let clock = 0; // seconds of motion; advances only while tracking
    let last = null;
    const synth = {
      kind: "synthetic",
      el: canvas,
      width: W,
      height: H,
      disc: { x: W / 2, y: H / 2, r: R },
      fresh: () => true,
      taken: () => {},
      stop: () => {},
      /** Advance the animation to `now` (ms) and draw the scene. */
      render(now) {
        if (demo.tracking && last !== null) clock += Math.min(0.1, (now - last) / 1000);
        last = now;
        const x = W / 2 + 110 * Math.sin(0.5 * clock);
        const y = H / 2 + 50 * Math.sin(0.8 * clock);
        synth.disc = { x, y, r: R };
        demo.disc = synth.disc;
        ctx.drawImage(background, 0, 0);
        ctx.fillStyle = "rgb(190, 38, 44)";
        ctx.beginPath();
        ctx.arc(x, y, R, 0, 2 * Math.PI);
        ctx.fill();
      },
    };
    return synth;
  }

  /** Size the picture and the overlay to fit the page, keeping the aspect ratio. */
  function layout() {
    if (!source || !source.width) return;
    if (ui.overlay.width !== source.width || ui.overlay.height !== source.height) {
      ui.overlay.width = source.width;
      ui.overlay.height = source.height;
    }
    const maxW = ui.stage.parentElement.clientWidth;
    const maxH = Math.max(240, window.innerHeight * 0.72);
    const scale = Math.min(maxW / source.width, maxH / source.height, 2);
    const w = `${Math.floor(source.width * scale)}px`;
    const h = `${Math.floor(source.height * scale)}px`;
    for (const el of [ui.stage, source.el, ui.overlay]) {
      el.style.width = w;
      el.style.height = h;
    }
  }

  // ---------------------------------------------------------------- outlines

  /** Video pixels per CSS pixel of the overlay. */
  function videoPerCss() {
    return source ? source.width / ui.overlay.getBoundingClientRect().width : 1;
  }

  /** A pointer event's position in video pixels [x, y]. */
  function toVideo(event) {
    const rect = ui.overlay.getBoundingClientRect();
    return [
      ((event.clientX - rect.left) * source.width) / rect.width,
      ((event.clientY - rect.top) * source.height) / rect.height,
    ];
  }

  /** Outlines can be drawn: a picture, and not while a stream is being stopped. */
  function editable() {
    return Boolean(source && !stopping);
  }

  function outlineReady(o) {
    if (!o) return false;
    if (o.kind === "circle") return o.radius >= MIN_OUTLINE_PX;
    if (o.kind === "box") {
      return (
        Math.abs(o.to[0] - o.from[0]) >= MIN_OUTLINE_PX &&
        Math.abs(o.to[1] - o.from[1]) >= MIN_OUTLINE_PX
      );
    }
    return o.points.length >= 3;
  }

  function dragShape() {
    const checked = document.querySelector('input[name="drag-shape"]:checked');
    return checked ? checked.value : "box";
  }

  function forgetOutlines() {
    outlines = [];
    draft = null;
    pending = [];
    controls = [];
    colours.clear();
    demo.outlines = 0;
    demo.pendingObjects = 0;
  }

  /** Colour of object `id`: the next colour of the palette the first time it is seen. */
  function colourOf(id) {
    if (!colours.has(id)) colours.set(id, PALETTE[colours.size % PALETTE.length]);
    return colours.get(id);
  }

  /** Colour a not-yet-tracked outline will get. */
  function nextColour(offset) {
    return PALETTE[(colours.size + offset) % PALETTE.length];
  }

  function objectCount() {
    const tracked = demo.lastObjects ? demo.lastObjects.length : 0;
    return (session ? tracked : 0) + outlines.length + pending.length;
  }

  /** A finished outline: kept for Track, or sent to the running session. */
  function finish(o) {
    draft = null;
    if (!outlineReady(o)) return;
    if (objectCount() >= MAX_OBJECTS) {
      setStatus(`At most ${MAX_OBJECTS} objects per session.`);
      return;
    }
    if (session) {
      sendObject(o);
    } else {
      outlines.push(o);
      demo.outlines = outlines.length;
      setStatus(
        `${outlines.length} object${outlines.length > 1 ? "s" : ""} outlined. ` +
          "Draw more, or press Track.",
      );
    }
    updateButtons();
  }

  function addPoint(p) {
    if (!draft || draft.kind !== "polygon") draft = { kind: "polygon", points: [] };
    const pts = draft.points;
    const near = (q, css) => Math.hypot(q[0] - p[0], q[1] - p[1]) <= css * videoPerCss();
    if (pts.length && near(pts[pts.length - 1], 3)) return; // second click of a double-click
    if (pts.length >= 3 && near(pts[0], 8)) {
      finish(draft); // clicked the first point again
      return;
    }
    pts.push(p);
  }

  function closePolygon() {
    if (draft && draft.kind === "polygon" && draft.points.length >= 3) {
      finish(draft);
    } else {
      setStatus("A polygon needs at least 3 points.");
    }
    updateButtons();
  }

  ui.overlay.addEventListener("pointerdown", (e) => {
    if (!editable() || e.button !== 0) return;
    ui.overlay.setPointerCapture(e.pointerId);
    press = { at: toVideo(e), cx: e.clientX, cy: e.clientY, dragging: false };
    if (source.kind === "file" && !session) source.el.pause(); // edit on a still picture
  });

  ui.overlay.addEventListener("pointermove", (e) => {
    if (!press) return;
    if (!press.dragging && Math.hypot(e.clientX - press.cx, e.clientY - press.cy) >= DRAG_PX) {
      press.dragging = true;
      press.shape = dragShape();
      press.polygon = draft && draft.kind === "polygon" ? draft : null; // resumed after
    }
    if (press.dragging) {
      const p = toVideo(e);
      const radius = Math.hypot(p[0] - press.at[0], p[1] - press.at[1]);
      draft =
        press.shape === "circle"
          ? { kind: "circle", center: press.at, radius }
          : { kind: "box", from: press.at, to: p };
    }
  });

  ui.overlay.addEventListener("pointerup", () => {
    if (!press) return;
    if (!press.dragging) addPoint(press.at);
    else {
      const polygon = press.polygon;
      finish(draft);
      draft = polygon;
    }
    press = null;
    updateButtons();
  });

  ui.overlay.addEventListener("pointercancel", () => {
    if (press && press.dragging) draft = press.polygon;
    press = null;
  });

  ui.overlay.addEventListener("dblclick", (e) => {
    e.preventDefault();
    if (editable()) closePolygon();
  });

  ui.overlay.addEventListener("keydown", (e) => {
    if (!editable()) return;
    if (e.key === "Enter") closePolygon();
    else if (e.key === "Escape") {
      if (draft) draft = null;
      else if (!session) clearOutlines();
    } else if (e.key === "Backspace") {
      if (draft && draft.kind === "polygon" && draft.points.length) draft.points.pop();
      else if (!session && outlines.length) outlines.pop();
      demo.outlines = outlines.length;
    } else return;
    e.preventDefault();
    updateButtons();
  });

  function clearOutlines() {
    outlines = [];
    draft = null;
    demo.outlines = 0;
    demo.lastNodes = null;
    demo.lastObjects = null;
    updateButtons();
  }

  /** The API's form of an outline ([x, y] video pixels, to 0.1 px). */
  function objectSpec(o) {
    const r1 = (v) => Math.round(v * 10) / 10;
    const snap = ui.snap.checked; // the server snaps the outline on the next frame
    if (o.kind === "circle") {
      const circle = { center: o.center.map(r1), radius: r1(o.radius), count: CIRCLE_NODES };
      return { circle, snap };
    }
    if (o.kind === "box") {
      const x0 = Math.min(o.from[0], o.to[0]);
      const y0 = Math.min(o.from[1], o.to[1]);
      const x1 = Math.max(o.from[0], o.to[0]);
      const y1 = Math.max(o.from[1], o.to[1]);
      return { box: [x0, y0, x1, y1].map(r1), snap };
    }
    return { nodes: o.points.map((p) => p.map(r1)), snap };
  }

  // ------------------------------------------------------------------- drawing

  function tracePath(ctx, pts, closed) {
    ctx.beginPath();
    pts.forEach((p, i) => (i ? ctx.lineTo(p[0], p[1]) : ctx.moveTo(p[0], p[1])));
    if (closed) ctx.closePath();
  }

  /** Stroke with a dark halo so the line reads on light and dark pictures. */
  function haloStroke(ctx, colour, width, dash = []) {
    ctx.setLineDash([]);
    ctx.strokeStyle = "rgba(0, 0, 0, 0.6)";
    ctx.lineWidth = width * 1.9;
    ctx.stroke();
    ctx.setLineDash(dash);
    ctx.strokeStyle = colour;
    ctx.lineWidth = width;
    ctx.stroke();
    ctx.setLineDash([]);
  }

  function drawDots(ctx, pts, colour, r) {
    ctx.fillStyle = colour;
    for (const p of pts) {
      ctx.beginPath();
      ctx.arc(p[0], p[1], r, 0, 2 * Math.PI);
      ctx.fill();
    }
  }

  /** Stroke an outline (dashed: not tracked yet). */
  function strokeOutline(ctx, o, colour, k, closed = true) {
    const dash = [6 * k, 4 * k];
    if (o.kind === "circle") {
      ctx.beginPath();
      ctx.arc(o.center[0], o.center[1], o.radius, 0, 2 * Math.PI);
      haloStroke(ctx, colour, 2 * k, dash);
      drawDots(ctx, [o.center], colour, 3 * k);
    } else if (o.kind === "box") {
      ctx.beginPath();
      ctx.rect(o.from[0], o.from[1], o.to[0] - o.from[0], o.to[1] - o.from[1]);
      haloStroke(ctx, colour, 2 * k, dash);
    } else {
      tracePath(ctx, o.points, closed);
      haloStroke(ctx, colour, 2 * k, dash);
      if (o.points.length <= 32) drawDots(ctx, o.points, colour, 3.5 * k);
    }
  }

  function drawOverlay() {
    const ctx = overlayCtx;
    ctx.clearRect(0, 0, ui.overlay.width, ui.overlay.height);
    if (!source) return;
    const k = videoPerCss(); // keep line widths constant on screen
    ctx.lineJoin = "round";
    if (session) {
      // those behind others first, so that the objects in front are drawn over them
      const depth = (o) => (o.behind ? o.behind.length : 0);
      const tracked = [...(demo.lastObjects || [])].sort((a, b) => depth(b) - depth(a));
      for (const o of tracked) {
        for (const piece of o.contours || [o.nodes]) {
          tracePath(ctx, piece, true);
          haloStroke(ctx, colourOf(o.id), 3 * k);
        }
      }
      pending.forEach((o, i) => strokeOutline(ctx, o, nextColour(i), k));
    } else {
      outlines.forEach((o, i) => strokeOutline(ctx, o, nextColour(i), k));
    }
    if (draft) {
      const offset = session ? pending.length : outlines.length;
      strokeOutline(ctx, draft, nextColour(offset), k, draft.kind !== "polygon");
    }
  }

  /** The list of objects beside the picture: colour, id, status and confidence. */
  function paintObjectList() {
    // [colour, label, key to remove it by (an object's id, an outline's index) or null]
    const rows = session
      ? (demo.lastObjects || []).map((o) => {
          const c = typeof o.confidence === "number" ? ` ${o.confidence.toFixed(2)}` : "";
          const under = o.behind && o.behind.length ? `, behind #${o.behind.join(", #")}` : "";
          return [colourOf(o.id), `#${o.id} ${o.status || "waiting"}${c}${under}`, o.id];
        })
      : outlines.map((o, i) => [nextColour(i), `${o.kind}, to track`, String(i)]);
    pending.forEach((o, i) => rows.push([nextColour(i), `${o.kind}, joining`, null]));
    // Rebuilt only when the objects change (a button replaced under the pointer would
    // lose its click); otherwise only the labels are updated in place.
    const structure = rows.map((r) => `${r[0]} ${r[2]}`).join("|");
    if (ui.objectList.dataset.structure === structure) {
      rows.forEach(([, label], i) => {
        const li = ui.objectList.children[i];
        if (li && li.firstChild.nodeValue !== label) li.firstChild.nodeValue = label;
      });
      return;
    }
    ui.objectList.dataset.structure = structure;
    ui.objectList.replaceChildren(
      ...rows.map(([colour, label, key]) => {
        const li = document.createElement("li");
        li.style.setProperty("--swatch", colour);
        li.append(label);
        if (key !== null) {
          const remove = document.createElement("button");
          remove.type = "button";
          remove.className = "remove";
          remove.dataset.key = key;
          remove.textContent = "×";
          remove.title = "Remove";
          const what = session ? `object #${key}` : `outline ${Number(key) + 1}`;
          remove.setAttribute("aria-label", `Remove ${what}`);
          li.append(" ", remove);
        }
        return li;
      }),
    );
  }

  function paintStats(now) {
    if (now - lastStatsPaint < 250) return;
    lastStatsPaint = now;
    resultTimes = resultTimes.filter((t) => now - t <= FPS_WINDOW_MS);
    if (session) {
      const span = Math.max(250, Math.min(FPS_WINDOW_MS, now - trackingSince));
      ui.fps.textContent = ((resultTimes.length * 1000) / span).toFixed(1);
    }
    ui.latency.textContent = latencyAvg === null ? "–" : `${Math.round(latencyAvg)} ms`;
    ui.dropped.textContent = String(demo.dropped);
    const r = demo.lastResult;
    ui.confidence.textContent = r ? `${r.confidence.toFixed(2)} ${r.status ?? ""}`.trim() : "–";
    ui.frame.textContent = r ? String(r.frame_index) : "–";
    paintObjectList();
  }

  /** The page's heartbeat: animate, draw, send when a frame is due. */
  function loop(now) {
    tick += 1;
    if (source && source.render) source.render(now);
    if (source && (ui.overlay.width !== source.width || ui.overlay.height !== source.height)) {
      layout(); // camera resolution changed
    }
    drawOverlay();
    paintStats(now);
    pump();
    requestAnimationFrame(loop);
  }

  // ------------------------------------------------------------------ streaming

  function authHeaders(key, extra = {}) {
    return key ? { ...extra, Authorization: `Bearer ${key}` } : extra;
  }

  async function httpError(res) {
    try {
      const body = await res.json();
      if (body && body.error) return `${res.status} ${body.error.code}: ${body.error.message}`;
    } catch (_) {
      // not JSON: fall through
    }
    return `HTTP ${res.status} ${res.statusText}`;
  }

  async function startTracking() {
    if (!source || session) return;
    if (draft && draft.kind === "polygon" && outlineReady(draft)) finish(draft);
    if (!outlines.length) return;
    clearError();
    // Always a session of several objects, so that more can join mid-stream.
    const body = { objects: outlines.map(objectSpec), ttl_seconds: SESSION_TTL_SECONDS };
    const key = ui.apiKey.value.trim();
    ui.track.disabled = true;
    setStatus("Creating a session…");
    let created;
    try {
      const res = await fetch("/v1/sessions", {
        method: "POST",
        headers: authHeaders(key, { "Content-Type": "application/json" }),
        body: JSON.stringify(body),
      });
      if (!res.ok) throw new Error(await httpError(res));
      created = await res.json();
    } catch (err) {
      showError(`Could not create a session: ${err.message}`);
      setStatus("Ready.");
      updateButtons();
      return;
    }
    session = { id: created.id, key };
    colours.clear();
    (created.objects || []).forEach((o) => colourOf(o.id)); // in the order drawn
    outlines = [];
    Object.assign(demo, {
      sessionId: created.id,
      sent: 0,
      results: 0,
      dropped: 0,
      outlines: 0,
      lastNodes: created.nodes,
      lastObjects: created.objects || null,
      lastResult: null,
      latencyMs: null,
      lastError: null,
      closed: null,
      lastResultDisc: null,
      lastResultTime: null,
    });
    inflight = [];
    resultTimes = [];
    latencyAvg = null;
    ui.fps.textContent = "–";
    openSocket(session);
    updateButtons();
  }

  function openSocket(s) {
    const scheme = location.protocol === "https:" ? "wss:" : "ws:";
    const query = s.key ? `?api_key=${encodeURIComponent(s.key)}` : "";
    const url = `${scheme}//${location.host}/v1/sessions/${encodeURIComponent(s.id)}/stream${query}`;
    const ws = new WebSocket(url);
    ws.binaryType = "arraybuffer";
    socket = ws;
    stopping = false;
    setStatus("Connecting…");

    ws.addEventListener("open", () => {
      if (ws !== socket) return;
      demo.tracking = true;
      trackingSince = performance.now();
      setStatus(`Tracking (session ${s.id.slice(0, 8)}…).`);
      if (source && source.kind === "file") source.el.play().catch(() => {});
      pump();
    });

    ws.addEventListener("message", (e) => {
      if (ws !== socket || typeof e.data !== "string") return;
      let msg;
      try {
        msg = JSON.parse(e.data);
      } catch (_) {
        showError("The server sent a message that is not JSON.");
        return;
      }
      onMessage(msg);
    });

    ws.addEventListener("close", (e) => {
      if (ws !== socket) return; // an older stream
      demo.closed = { code: e.code, reason: e.reason };
      socket = null;
      demo.tracking = false;
      inflight = [];
      pending = [];
      controls = [];
      demo.pendingObjects = 0;
      const reason = e.reason ? `: ${e.reason}` : "";
      if (stopping) {
        setStatus(`Stopped (socket closed, code ${e.code}).`);
      } else {
        const hint = { 4401: " (API key missing or wrong)", 4404: " (session expired)" };
        showError(`Stream closed, code ${e.code}${reason}${hint[e.code] || ""}`, {
          code: e.code,
          message: e.reason,
        });
        setStatus("Not tracking.");
        endSession(); // free the server-side session (harmless if already gone)
      }
      updateButtons();
    });
  }

  /** Forget the frames a result accounts for; returns the processed frame's entry. */
  function settle(dropped) {
    let entry = null;
    for (let n = Math.min(dropped + 1, inflight.length); n > 0; n -= 1) entry = inflight.shift();
    return entry;
  }

  function onMessage(msg) {
    // Frame results and frame errors both carry "dropped": d dropped frames + 1 processed.
    const entry = "dropped" in msg ? settle(msg.dropped) : null;
    const now = performance.now();
    if (msg.type === "frame") {
      demo.results += 1;
      demo.dropped += msg.dropped;
      demo.lastNodes = msg.nodes;
      demo.lastObjects = msg.objects || null;
      demo.lastResult = msg;
      resultTimes.push(now);
      if (entry) {
        demo.latencyMs = now - entry.sentAt;
        latencyAvg =
          latencyAvg === null ? demo.latencyMs : 0.8 * latencyAvg + 0.2 * demo.latencyMs;
        demo.lastResultDisc = entry.disc;
        demo.lastResultTime = entry.time;
      }
    } else if (msg.type === "object") {
      // acknowledged: it takes effect from the next frame on
      if (controls.shift() === "add") pending.shift();
      demo.pendingObjects = pending.length;
      const others = (demo.lastObjects || []).filter((o) => o.id !== msg.id);
      if (msg.removed) demo.lastObjects = others;
      else {
        colourOf(msg.id);
        demo.lastObjects = [...others, msg];
      }
    } else if (msg.type === "error") {
      const err = msg.error || {};
      if (entry) demo.dropped += msg.dropped;
      else if (controls.length && controls.shift() === "add") pending.shift(); // refused
      demo.pendingObjects = pending.length;
      showError(`Server error ${err.status} ${err.code}: ${err.message}`, err);
    }
    pump();
  }

  /** Capture, encode and send one frame when the socket and the pipeline allow. */
  function pump() {
    const ws = socket;
    if (!ws || stopping || ws.readyState !== WebSocket.OPEN || !source || !source.width) return;
    if (encoding || inflight.length >= MAX_IN_FLIGHT) return;
    if (tick === lastCaptureTick || !source.fresh()) return; // wait for a new picture
    lastCaptureTick = tick;
    const time = source.kind === "file" ? source.el.currentTime : null;
    source.taken();
    const disc = source.disc ? { ...source.disc } : null;
    capture.width = source.width;
    capture.height = source.height;
    captureCtx.drawImage(source.el, 0, 0, capture.width, capture.height);
    encoding = true;
    capture.toBlob(
      async (blob) => {
        try {
          if (!blob) throw new Error("the browser could not encode JPEG");
          const data = await blob.arrayBuffer();
          if (ws !== socket || ws.readyState !== WebSocket.OPEN) return;
          inflight.push({ sentAt: performance.now(), disc, time });
          ws.send(data);
          demo.sent += 1;
        } catch (err) {
          showError(`Could not send a frame: ${err.message}`);
        } finally {
          encoding = false;
        }
        pump(); // fill the pipeline up to MAX_IN_FLIGHT
      },
      "image/jpeg",
      JPEG_QUALITY,
    );
  }

  /** Add an outline drawn mid-stream to the session (a WebSocket control message). */
  function sendObject(o) {
    const ws = socket;
    if (!ws || ws.readyState !== WebSocket.OPEN) {
      setStatus("Not connected yet: draw the object again in a moment.");
      return;
    }
    pending.push(o);
    controls.push("add");
    demo.pendingObjects = pending.length;
    ws.send(JSON.stringify({ add_object: objectSpec(o) }));
  }

  /** Stop tracking object `id` (mid-stream), or forget outline `index` (before tracking). */
  function removeObject(key) {
    if (!session) {
      outlines.splice(Number(key), 1);
      demo.outlines = outlines.length;
      updateButtons();
      return;
    }
    const ws = socket;
    if (!ws || ws.readyState !== WebSocket.OPEN) return;
    controls.push("remove");
    ws.send(JSON.stringify({ remove_object: key }));
  }

  /** Wait for `ws` to close, at most `ms` milliseconds. */
  function closed(ws, ms) {
    if (ws.readyState === WebSocket.CLOSED) return Promise.resolve();
    return new Promise((resolve) => {
      ws.addEventListener("close", resolve, { once: true });
      setTimeout(resolve, ms);
    });
  }

  /** DELETE the session (quietly when `quiet`); the page keeps the last contour. */
  async function endSession(quiet = true) {
    const s = session;
    if (!s) return;
    session = null;
    // The last contours become the outlines, to track again.
    const last = demo.lastObjects || (demo.lastNodes ? [{ nodes: demo.lastNodes }] : []);
    outlines = last.map((o) => ({ kind: "polygon", points: o.nodes || o.contours[0] }));
    demo.outlines = outlines.length;
    pending = [];
    controls = [];
    demo.pendingObjects = 0;
    colours.clear();
    updateButtons();
    try {
      const res = await fetch(`/v1/sessions/${encodeURIComponent(s.id)}`, {
        method: "DELETE",
        headers: authHeaders(s.key),
      });
      if (!res.ok && res.status !== 404 && !quiet) throw new Error(await httpError(res));
    } catch (err) {
      if (!quiet) showError(`Could not delete the session: ${err.message}`);
    }
  }

  /** Wait until every frame sent has been answered, at most `ms` milliseconds. */
  function drained(ms) {
    const until = performance.now() + ms;
    return new Promise((resolve) => {
      const check = () =>
        (!inflight.length && !encoding) || performance.now() > until || !socket
          ? resolve()
          : setTimeout(check, 10);
      check();
    });
  }

  async function stopTracking() {
    if (!session) return;
    stopping = true; // pump() sends nothing more
    const ws = socket;
    ui.stop.disabled = true;
    setStatus("Stopping…");
    // Let the frames in flight come back, close, then delete: closing under a
    // frame being tracked makes needless work, and a session deleted under a
    // live stream ends it with 4404.
    await drained(1500);
    if (ws && ws.readyState <= WebSocket.OPEN) {
      ws.close(1000, "stopped by user");
      await closed(ws, 1500);
    }
    if (source && source.kind === "file") source.el.pause();
    await endSession(false);
    setStatus(`Stopped. ${demo.results} results; the last contours can be tracked again.`);
  }

  // ---------------------------------------------------------------- controls

  function updateButtons() {
    const idle = !session;
    const closable = Boolean(draft && draft.kind === "polygon" && draft.points.length >= 3);
    ui.track.disabled = !(idle && source && (outlines.length || closable));
    ui.stop.disabled = idle;
    ui.clear.disabled = !(idle && (outlines.length || draft));
    ui.closePolygon.disabled = !(source && closable);
    ui.file.disabled = !idle;
    ui.camera.disabled = !idle;
    ui.overlay.classList.toggle("editing", Boolean(source));
  }

  ui.file.addEventListener("change", () => {
    const file = ui.file.files && ui.file.files[0];
    if (!file) return;
    clearError();
    useVideoFile(file);
  });
  ui.video.addEventListener("error", () => {
    if (ui.video.getAttribute("src")) showError("This video cannot be played by the browser.");
  });
  ui.video.addEventListener("ended", () => {
    if (session) setStatus("The video ended: press Stop.");
  });
  ui.camera.addEventListener("click", useCamera);
  ui.closePolygon.addEventListener("click", closePolygon);
  ui.clear.addEventListener("click", clearOutlines);
  ui.objectList.addEventListener("click", (e) => {
    const button = e.target.closest("button.remove");
    if (button && !stopping) removeObject(button.dataset.key);
  });
  ui.track.addEventListener("click", startTracking);
  ui.stop.addEventListener("click", stopTracking);
  window.addEventListener("resize", layout);
  window.addEventListener("pagehide", () => {
    // Best effort: free the server-side session when the page goes away.
    if (!session) return;
    if (socket) socket.close(1000, "page closed"); // scripts may only use 1000 or 3000-4999
    fetch(`/v1/sessions/${encodeURIComponent(session.id)}`, {
      method: "DELETE",
      headers: authHeaders(session.key),
      keepalive: true,
    }).catch(() => {});
  });

  if (params.get("demo") === "synthetic") {
    setSource(makeSynthetic());
    setStatus("Synthetic scene: drag a box around the red disc, then press Track.");
  }
  updateButtons();
  requestAnimationFrame(loop);
})();
