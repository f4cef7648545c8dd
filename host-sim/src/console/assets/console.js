// The teaching console's page (host-sim teach). Plain JavaScript, no build step, nothing loaded
// from anywhere but the console itself. The console sends `scene` once, `trace` once, then a
// `state` after every change; the page sends commands (host-sim/src/console/wire.rs).
'use strict';

(() => {
  const token = new URLSearchParams(location.search).get('token') || '';
  const $ = (id) => document.getElementById(id);
  const view = $('view');
  const ctx = view.getContext('2d');
  const minimap = $('minimap');
  const lossCanvas = $('loss');

  let socket = null;
  let scene = null;
  let state = null;
  let trace = [];
  const lossHistory = [];
  const picture = new Image();
  let pictureReady = false;
  let mode = 'action';
  let cursor = null; // an allowed trajectory chosen with [ and ]
  let hover = null;
  let candidate = null; // the other trajectory of preference mode
  let candidateTick = null;
  let showTeacher = true;
  let lastNotice = 0;
  let dirty = false;
  const zoomLevels = [70, 130, 200, 300];
  let zoom = 2;

  // What was drawn last, for whoever checks the page (the browser test reads it).
  const drawn = { map: false, trajectories: 0, allowed: 0, chosen: null, tick: null };

  const COLORS = {
    door: '#96591e', stairs: '#dc1e1e', chair: '#1eaa3c',
    allowed: 'rgba(37, 99, 235, 0.55)', blocked: 'rgba(220, 38, 38, 0.28)',
    chosen: '#16a34a', now: '#15803d', teacher: '#a855f7', hover: '#f59e0b',
    candidate: '#db2777', trace: '#f97316', car: '#111827',
  };

  // Every control of the page: its button, its key, what it does. A new kind of feedback is one
  // more entry here (and one variant of teach::person::Teaching on the console's side).
  const CONTROLS = [
    { group: 'Run', id: 'play', label: 'Play / pause', key: ' ', keyLabel: 'Space',
      run: () => send({ cmd: state && state.running ? 'pause' : 'play' }) },
    { group: 'Run', id: 'step', label: 'Step', key: '.', run: () => send({ cmd: 'step' }) },
    { group: 'Run', id: 'slower', label: 'Slower', key: '-', run: () => changeSpeed(-1) },
    { group: 'Run', id: 'faster', label: 'Faster', key: '+', also: ['='], run: () => changeSpeed(1) },
    { group: 'Run', id: 'zoom', label: 'Zoom', key: 'z', run: () => { zoom = (zoom + 1) % zoomLevels.length; redraw(); } },
    { group: 'Go there', id: 'prev', label: '◀', key: '[', run: () => moveCursor(-1) },
    { group: 'Go there', id: 'next', label: '▶', key: ']', run: () => moveCursor(1) },
    { group: 'Go there', id: 'go', label: 'Go there', key: 'Enter', run: () => goThere(cursor) },
    { group: 'Preference', id: 'preference', label: 'Preference mode', key: 'p', run: togglePreference },
    { group: 'Preference', id: 'prefer-learner', label: "Learner's (1) better", key: '1', run: () => answer(true) },
    { group: 'Preference', id: 'prefer-other', label: 'Other (2) better', key: '2', run: () => answer(false) },
    { group: 'Preference', id: 'another', label: 'Another', key: 'n', run: () => newCandidate(true) },
    { group: 'Say', id: 'say-avoid-doors', label: 'Avoid doors', key: 'd', say: 'avoid-doors' },
    { group: 'Say', id: 'say-avoid-stairs', label: 'Avoid stairs', key: 's', say: 'avoid-stairs' },
    { group: 'Say', id: 'say-avoid-chairs', label: 'Avoid chairs', key: 'c', say: 'avoid-chairs' },
    { group: 'Say', id: 'say-stay-on-path', label: 'Stay on the path', key: 'l', say: 'stay-on-path' },
    { group: 'Say', id: 'say-keep-right', label: 'Keep right', key: 'r', say: 'keep-right' },
    { group: 'Say', id: 'say-keep-off-walls', label: 'Keep off the walls', key: 'w', say: 'keep-off-walls' },
    // Reward and correct/incorrect judge the learner's action of the tick shown; a reward is in
    // hundredths of a unit (firmware-core's RewardFeedback, -100 to 100).
    { group: 'Reward', id: 'reward-minus-1', label: '−1', key: '7', reward: -100 },
    { group: 'Reward', id: 'reward-minus-half', label: '−½', key: '8', reward: -50 },
    { group: 'Reward', id: 'reward-plus-half', label: '+½', key: '9', reward: 50 },
    { group: 'Reward', id: 'reward-plus-1', label: '+1', key: '0', reward: 100 },
    { group: 'Mark', id: 'mark-correct', label: 'Correct', key: 'g', correct: true },
    { group: 'Mark', id: 'mark-incorrect', label: 'Incorrect', key: 'b', correct: false },
    // Good or bad over the last ticks up to the one shown: as many as the learner remembers (the
    // scene's span_ticks).
    { group: 'Last ticks', id: 'span-good', label: 'Good', key: 'v', good: true },
    { group: 'Last ticks', id: 'span-bad', label: 'Bad', key: 'x', good: false },
    { group: 'Stop', id: 'estop', label: 'E-STOP', key: 'Escape', keyLabel: 'Esc',
      run: () => teach({ kind: 'estop', content: {} }) },
    { group: 'Stop', id: 'finish', label: 'Finish session', key: null, run: finish },
    { group: 'Show', id: 'teacher-line', label: "Teacher's choice", key: 't', run: () => { showTeacher = !showTeacher; redraw(); } },
    { group: 'Show', id: 'help-button', label: 'Keys', key: '?', run: () => { $('help').hidden = !$('help').hidden; } },
  ];
  // How the count of each kind of teaching (Teaching::KINDS, in the scene's `kinds`) reads; a
  // kind without a label here shows its name.
  const KIND_LABELS = {
    action: 'go-there', preference: 'preferences', statement: 'statements', estop: 'E-stops',
    reward: 'rewards', correctness: 'marks', span: 'spans',
  };
  for (const c of CONTROLS) {
    if (c.say) c.run = () => teach({ kind: 'statement', content: { statement: c.say } });
    if (c.reward) c.run = () => teach({ kind: 'reward', content: { hundredths: c.reward } });
    if (c.correct !== undefined) {
      c.run = () => teach({ kind: 'correctness', content: { correct: c.correct } });
    }
    if (c.good !== undefined) {
      c.run = () => scene && teach({ kind: 'span', content: { ticks: scene.span_ticks, good: c.good } });
    }
  }

  // ---- connection ----------------------------------------------------------------------------

  function connect() {
    socket = new WebSocket(`ws://${location.host}/ws?token=${encodeURIComponent(token)}`);
    socket.onmessage = (event) => {
      let message;
      try { message = JSON.parse(event.data); } catch (e) { return; }
      if (message.type === 'scene') onScene(message);
      else if (message.type === 'trace') trace = message.points;
      else if (message.type === 'state') onState(message);
      else if (message.type === 'error') notice('error', message.text);
    };
    socket.onclose = () => {
      if (!state || !state.finished) setStatus('disconnected', 'disconnected');
      for (const b of document.querySelectorAll('footer button')) b.disabled = true;
    };
  }

  function send(command) {
    if (socket && socket.readyState === WebSocket.OPEN) socket.send(JSON.stringify(command));
  }

  function teach(teaching) {
    if (!state) return;
    send({ cmd: 'teach', tick: state.tick, teaching });
  }

  // ---- what the console says -----------------------------------------------------------------

  function onScene(s) {
    scene = s;
    $('scenario').textContent = `${s.scenario}${s.description ? ' · ' + s.description : ''}`;
    $('learner').textContent = s.learner;
    $('teacher').textContent = s.teacher ? `preset ${s.teacher}` : 'the scenario\'s teacher';
    const weights = $('weights');
    weights.textContent = '';
    for (const f of s.features) {
      const row = document.createElement('div');
      row.className = 'row';
      row.dataset.feature = f;
      row.innerHTML = '<span class="name"></span><span class="bar"><span class="fill"></span></span><span class="value"></span>';
      row.querySelector('.name').textContent = f;
      weights.appendChild(row);
    }
    picture.onload = () => { pictureReady = true; redraw(); };
    picture.src = `/map.png?token=${encodeURIComponent(token)}`;
  }

  function onState(s) {
    const previous = state;
    state = s;
    if (!previous || previous.tick !== s.tick) {
      if (previous && s.tick > previous.tick) {
        if (s.reset) trace.push(null);
        trace.push([s.pose[0], s.pose[1]]);
      }
      if (s.latent_loss !== null) {
        lossHistory.push([s.tick, s.latent_loss]);
        if (lossHistory.length > 300) lossHistory.shift();
      }
      if (cursor !== null && !s.allowed.includes(cursor)) cursor = null;
    }
    if (mode === 'preference' && (candidateTick !== s.tick || !s.allowed.includes(candidate))) {
      newCandidate(false);
    }
    $('tick').textContent = s.tick;
    $('corrections').textContent = s.corrections;
    $('laps').textContent = s.laps;
    $('progress').textContent = `${s.progress.toFixed(1)} m`;
    $('speed').textContent = `${s.speed}×`;
    if (s.finished) setStatus('finished', 'finished');
    else if (s.estopped) setStatus('estopped', 'E-STOPPED');
    else if (s.running) setStatus('running', `running ${s.speed}×`);
    else setStatus('paused', 'paused');
    showWeights(s.weights);
    const t = s.teachings;
    $('teachings').textContent = (scene ? scene.kinds : Object.keys(t))
      .map((k) => `${t[k]} ${KIND_LABELS[k] || k}`)
      .join(' · ');
    showLink(s.link);
    if (s.notice && s.notice.seq !== lastNotice) {
      lastNotice = s.notice.seq;
      notice(s.notice.level, s.notice.text);
    }
    if (s.finished) showEnd(s);
    redraw();
  }

  function setStatus(cls, text) {
    const el = $('status');
    el.className = cls;
    el.textContent = text;
  }

  function notice(level, text) {
    const el = $('notice');
    el.className = level;
    el.textContent = text;
  }

  function showWeights(w) {
    const scale = Math.max(1e-6, ...w.map(Math.abs));
    const rows = $('weights').children;
    for (let i = 0; i < rows.length && i < w.length; i++) {
      const row = rows[i];
      row.dataset.value = String(w[i]);
      const fill = row.querySelector('.fill');
      const half = 50 * Math.abs(w[i]) / scale;
      fill.style.left = w[i] < 0 ? `${50 - half}%` : '50%';
      fill.style.width = `${half}%`;
      fill.classList.toggle('negative', w[i] < 0);
      row.querySelector('.value').textContent = w[i].toFixed(3);
    }
  }

  function showLink(link) {
    const el = $('link');
    if (!link) {
      el.textContent = 'in process (no link)';
      el.dataset.connected = '';
      return;
    }
    el.dataset.connected = String(link.connected);
    el.textContent = `${link.address}: ${link.connected ? 'connected' : 'not connected'} · ` +
      `${link.retransmissions} retransmissions · ${link.stops} stops · ` +
      `${link.car_restarts} car restarts · ${link.refused} refused · ${link.link_errors} link errors`;
  }

  function showEnd(s) {
    const el = $('ended');
    el.hidden = false;
    el.innerHTML = '<h2>Session ended</h2><p class="why"></p><p>Files: <code class="dir"></code></p>' +
      '<p>Replay it: <code class="replay"></code></p>';
    el.querySelector('.why').textContent = s.ended_by || '';
    el.querySelector('.dir').textContent = s.dir;
    el.querySelector('.replay').textContent = `host-sim replay-session ${s.dir}`;
    for (const b of document.querySelectorAll('footer button')) b.disabled = true;
  }

  // ---- teaching ------------------------------------------------------------------------------

  function goThere(action) {
    if (action === null || action === undefined || !state) return;
    teach({ kind: 'action', content: { action } });
  }

  function sortedAllowed() {
    if (!scene || !state) return [];
    const end = (a) => scene.lattice[a][scene.lattice[a].length - 1];
    // Left to right as the car sees them.
    return [...state.allowed].sort((a, b) => end(b)[1] - end(a)[1] || a - b);
  }

  function moveCursor(step) {
    const list = sortedAllowed();
    if (!list.length) return;
    let i = list.indexOf(cursor);
    if (i < 0) i = Math.max(0, list.indexOf(state.chosen));
    else i = (i + step + list.length) % list.length;
    cursor = list[i];
    redraw();
  }

  function togglePreference() {
    mode = mode === 'preference' ? 'action' : 'preference';
    const el = $('mode');
    el.className = mode;
    $('preference').classList.toggle('on', mode === 'preference');
    if (mode === 'preference') {
      newCandidate(true);
      el.textContent = 'preference mode: is the learner\'s choice (1, green) or the other (2, pink) better? Click a trajectory to make it the other.';
    } else {
      el.textContent = 'action mode: click a trajectory to say “go there”';
    }
    redraw();
  }

  function newCandidate(force) {
    if (!state) return;
    const others = state.allowed.filter((a) => a !== state.chosen);
    if (!others.length) { candidate = null; return; }
    if (force || !others.includes(candidate) || candidateTick !== state.tick) {
      const pool = others.length > 1 ? others.filter((a) => a !== candidate) : others;
      candidate = pool[Math.floor(Math.random() * pool.length)];
    }
    candidateTick = state.tick;
    redraw();
  }

  function answer(learnersBetter) {
    if (mode !== 'preference' || !state || state.chosen === null || candidate === null) {
      notice('warn', 'press P for preference mode first');
      return;
    }
    const [preferred, other] = learnersBetter ? [state.chosen, candidate] : [candidate, state.chosen];
    teach({ kind: 'preference', content: { preferred, other } });
    newCandidate(true);
  }

  function changeSpeed(step) {
    if (!scene || !state) return;
    const speeds = scene.speeds;
    let i = speeds.indexOf(state.speed);
    if (i < 0) i = speeds.indexOf(1);
    const j = Math.min(speeds.length - 1, Math.max(0, i + step));
    send({ cmd: 'speed', value: speeds[j] });
  }

  function finish() {
    send({ cmd: 'finish' });
  }

  // ---- drawing -------------------------------------------------------------------------------

  function redraw() {
    if (dirty) return;
    dirty = true;
    requestAnimationFrame(() => { dirty = false; draw(); });
  }

  // World (m) to view pixels: north up, the car in the middle.
  function transform() {
    const s = zoomLevels[zoom];
    const [cx, cy] = state.pose;
    return {
      s,
      x: (x) => view.width / 2 + (x - cx) * s,
      y: (y) => view.height / 2 - (y - cy) * s,
      world: (px, py) => [cx + (px - view.width / 2) / s, cy - (py - view.height / 2) / s],
    };
  }

  function trajectoryWorld(a) {
    const [x, y, th] = state.pose;
    const c = Math.cos(th), s = Math.sin(th);
    return scene.lattice[a].map(([u, v]) => [x + c * u - s * v, y + s * u + c * v]);
  }

  function polyline(t, points, color, width, dash) {
    ctx.beginPath();
    points.forEach(([x, y], i) => (i ? ctx.lineTo(t.x(x), t.y(y)) : ctx.moveTo(t.x(x), t.y(y))));
    ctx.strokeStyle = color;
    ctx.lineWidth = width;
    ctx.setLineDash(dash || []);
    ctx.stroke();
    ctx.setLineDash([]);
  }

  function label(t, x, y, text, color) {
    ctx.font = 'bold 13px system-ui, sans-serif';
    ctx.textAlign = 'center';
    ctx.lineWidth = 3;
    ctx.strokeStyle = 'rgba(255,255,255,0.9)';
    ctx.strokeText(text, t.x(x), t.y(y));
    ctx.fillStyle = color;
    ctx.fillText(text, t.x(x), t.y(y));
  }

  function draw() {
    if (!scene || !state) return;
    const t = transform();
    ctx.fillStyle = '#b4b4b4';
    ctx.fillRect(0, 0, view.width, view.height);
    const p = scene.picture;
    if (pictureReady) {
      ctx.imageSmoothingEnabled = false;
      const scale = p.metres_per_pixel * t.s;
      ctx.drawImage(picture, t.x(p.origin[0]), t.y(p.origin[1] + p.height * p.metres_per_pixel),
        p.width * scale, p.height * scale);
    }
    // The semantic objects, labelled.
    for (const o of scene.objects) {
      ctx.strokeStyle = COLORS[o.class];
      ctx.lineWidth = 2;
      ctx.beginPath();
      if (o.shape.disc) {
        ctx.arc(t.x(o.x), t.y(o.y), o.shape.disc.radius * t.s, 0, 2 * Math.PI);
      } else {
        const { width, height, yaw } = o.shape.rect;
        const c = Math.cos(yaw), s = Math.sin(yaw);
        [[-1, -1], [1, -1], [1, 1], [-1, 1]].forEach(([i, j], k) => {
          const u = i * width / 2, v = j * height / 2;
          const x = t.x(o.x + c * u - s * v), y = t.y(o.y + s * u + c * v);
          if (k) ctx.lineTo(x, y); else ctx.moveTo(x, y);
        });
        ctx.closePath();
      }
      ctx.stroke();
      label(t, o.x, o.y + 0.05, o.class, COLORS[o.class]);
    }
    // Where the car has been.
    ctx.beginPath();
    let pen = false;
    for (const q of trace) {
      if (!q) { pen = false; continue; }
      if (pen) ctx.lineTo(t.x(q[0]), t.y(q[1])); else ctx.moveTo(t.x(q[0]), t.y(q[1]));
      pen = true;
    }
    ctx.strokeStyle = COLORS.trace;
    ctx.lineWidth = 2;
    ctx.stroke();
    drawCar(t);
    // The 64 trajectories: the blocked ones faint, the allowed ones blue, the marked ones on top.
    const allowed = new Set(state.allowed);
    let count = 0;
    for (let a = 0; a < scene.lattice.length; a++) {
      if (allowed.has(a)) continue;
      polyline(t, trajectoryWorld(a), COLORS.blocked, 1, [4, 4]);
      count++;
    }
    for (const a of state.allowed) {
      polyline(t, trajectoryWorld(a), COLORS.allowed, 1.5);
      count++;
    }
    const marks = [];
    if (showTeacher && state.teacher_choice !== null) marks.push([state.teacher_choice, COLORS.teacher, 2.5, [6, 4], 'teacher']);
    if (state.chosen !== null) marks.push([state.chosen, COLORS.chosen, 4.5, null, mode === 'preference' ? '1' : 'learner']);
    if (state.choice_now !== null && state.choice_now !== state.chosen) marks.push([state.choice_now, COLORS.now, 3, [3, 3], 'now']);
    if (mode === 'preference' && candidate !== null) marks.push([candidate, COLORS.candidate, 4.5, null, '2']);
    if (hover !== null && allowed.has(hover)) marks.push([hover, COLORS.hover, 3, null, null]);
    if (cursor !== null && allowed.has(cursor)) marks.push([cursor, COLORS.hover, 3.5, [8, 3], 'Enter']);
    for (const [a, color, width, dash, text] of marks) {
      const pts = trajectoryWorld(a);
      polyline(t, pts, color, width, dash);
      if (text) {
        const [x, y] = pts[pts.length - 1];
        label(t, x, y + 0.08, text, color);
      }
    }
    drawn.map = pictureReady;
    drawn.trajectories = count;
    drawn.allowed = state.allowed.length;
    drawn.chosen = state.chosen;
    drawn.tick = state.tick;
    drawMinimap();
    drawLoss();
  }

  function drawCar(t) {
    const [x, y, th] = state.pose;
    const c = Math.cos(th), s = Math.sin(th);
    const shape = [[-0.1, -0.14], [0.42, -0.14], [0.5, 0], [0.42, 0.14], [-0.1, 0.14]];
    ctx.beginPath();
    shape.forEach(([u, v], i) => {
      const px = t.x(x + c * u - s * v), py = t.y(y + s * u + c * v);
      if (i) ctx.lineTo(px, py); else ctx.moveTo(px, py);
    });
    ctx.closePath();
    ctx.fillStyle = state.estopped ? 'rgba(220, 38, 38, 0.45)' : 'rgba(17, 24, 39, 0.18)';
    ctx.fill();
    ctx.strokeStyle = state.estopped ? COLORS.blocked : COLORS.car;
    ctx.lineWidth = 1.5;
    ctx.stroke();
  }

  function drawMinimap() {
    const m = minimap.getContext('2d');
    const p = scene.picture;
    const k = Math.min(minimap.width / p.width, minimap.height / p.height);
    m.fillStyle = '#fafafa';
    m.fillRect(0, 0, minimap.width, minimap.height);
    if (pictureReady) {
      m.imageSmoothingEnabled = true;
      m.drawImage(picture, 0, 0, p.width * k, p.height * k);
    }
    const px = (x) => (x - p.origin[0]) / p.metres_per_pixel * k;
    const py = (y) => (p.height - (y - p.origin[1]) / p.metres_per_pixel) * k;
    m.beginPath();
    let pen = false;
    for (const q of trace) {
      if (!q) { pen = false; continue; }
      if (pen) m.lineTo(px(q[0]), py(q[1])); else m.moveTo(px(q[0]), py(q[1]));
      pen = true;
    }
    m.strokeStyle = COLORS.trace;
    m.lineWidth = 1.5;
    m.stroke();
    const s = zoomLevels[zoom];
    const w = view.width / s, h = view.height / s;
    m.strokeStyle = '#2563eb';
    m.lineWidth = 1;
    m.strokeRect(px(state.pose[0] - w / 2), py(state.pose[1] + h / 2), w / p.metres_per_pixel * k, h / p.metres_per_pixel * k);
    m.beginPath();
    m.arc(px(state.pose[0]), py(state.pose[1]), 3, 0, 2 * Math.PI);
    m.fillStyle = COLORS.car;
    m.fill();
  }

  function drawLoss() {
    const g = lossCanvas.getContext('2d');
    const w = lossCanvas.width, h = lossCanvas.height;
    g.fillStyle = '#fafafa';
    g.fillRect(0, 0, w, h);
    if (!showTeacher || !lossHistory.length) return;
    const top = Math.max(1, ...lossHistory.map(([, l]) => l));
    g.beginPath();
    lossHistory.forEach(([, l], i) => {
      const x = (i / 299) * (w - 2) + 1, y = h - 14 - (l / top) * (h - 20);
      if (i) g.lineTo(x, y); else g.moveTo(x, y);
    });
    g.strokeStyle = COLORS.teacher;
    g.lineWidth = 1.5;
    g.stroke();
    const last = lossHistory[lossHistory.length - 1][1];
    g.fillStyle = '#374151';
    g.font = '11px system-ui, sans-serif';
    g.fillText(`now ${last.toFixed(2)} · max ${top.toFixed(2)} · last ${lossHistory.length} ticks`, 4, h - 3);
  }

  // ---- pointing ------------------------------------------------------------------------------

  function eventToView(event) {
    const r = view.getBoundingClientRect();
    return [(event.clientX - r.left) * view.width / r.width, (event.clientY - r.top) * view.height / r.height];
  }

  // The allowed trajectory nearest to a view point, within 14 pixels (its first 0.3 m, where
  // all trajectories meet at the car, does not count). Where several pass as near (a short
  // trajectory lies along the start of a long one), the one that ends nearest wins.
  function pick(px, py) {
    if (!scene || !state) return null;
    const t = transform();
    let best = null, bestScore = Infinity;
    for (const a of state.allowed) {
      const pts = trajectoryWorld(a).map(([x, y]) => [t.x(x), t.y(y)]);
      let d = Infinity;
      for (let i = 3; i + 1 < pts.length; i++) d = Math.min(d, segmentDistance(px, py, pts[i], pts[i + 1]));
      if (d >= 14) continue;
      const [ex, ey] = pts[pts.length - 1];
      const score = d + 0.2 * Math.hypot(px - ex, py - ey);
      if (score < bestScore) { bestScore = score; best = a; }
    }
    return best;
  }

  function segmentDistance(px, py, [ax, ay], [bx, by]) {
    const dx = bx - ax, dy = by - ay;
    const l = dx * dx + dy * dy;
    const u = l ? Math.max(0, Math.min(1, ((px - ax) * dx + (py - ay) * dy) / l)) : 0;
    return Math.hypot(px - ax - u * dx, py - ay - u * dy);
  }

  view.addEventListener('mousemove', (event) => {
    const a = pick(...eventToView(event));
    if (a !== hover) { hover = a; redraw(); }
  });
  view.addEventListener('mouseleave', () => { hover = null; redraw(); });
  view.addEventListener('click', (event) => {
    const a = pick(...eventToView(event));
    if (a === null) return;
    if (mode === 'preference') {
      if (a === state.chosen) { notice('warn', 'that is the learner\'s own choice: pick another as the other'); return; }
      candidate = a;
      candidateTick = state.tick;
      redraw();
    } else {
      goThere(a);
    }
  });

  // The view point (page pixels) of the end of trajectory `a`, for whoever checks the page.
  function pointOf(a) {
    const t = transform();
    const pts = trajectoryWorld(a);
    const [x, y] = pts[pts.length - 1];
    const r = view.getBoundingClientRect();
    return {
      x: r.left + t.x(x) * r.width / view.width,
      y: r.top + t.y(y) * r.height / view.height,
    };
  }

  // ---- controls ------------------------------------------------------------------------------

  function buildControls() {
    const footer = $('controls');
    const groups = new Map();
    const keys = $('keys');
    for (const c of CONTROLS) {
      if (!groups.has(c.group)) {
        const g = document.createElement('div');
        g.className = 'group';
        g.innerHTML = '<span></span>';
        g.firstChild.textContent = c.group;
        footer.appendChild(g);
        groups.set(c.group, g);
      }
      const b = document.createElement('button');
      b.id = c.id;
      b.type = 'button';
      b.textContent = c.label;
      const keyName = c.keyLabel || c.key;
      if (keyName) {
        const k = document.createElement('kbd');
        k.textContent = keyName.length === 1 ? keyName.toUpperCase() : keyName;
        b.appendChild(k);
        const row = keys.insertRow();
        row.insertCell().textContent = k.textContent;
        row.insertCell().textContent = `${c.group}: ${c.label}`;
      }
      b.addEventListener('click', () => { c.run(); b.blur(); });
      groups.get(c.group).appendChild(b);
    }
  }

  document.addEventListener('keydown', (event) => {
    if (event.ctrlKey || event.metaKey || event.altKey) return;
    const key = event.key.length === 1 ? event.key.toLowerCase() : event.key;
    const c = CONTROLS.find((x) => x.key === key || (x.also && x.also.includes(key)));
    if (!c || (state && state.finished)) return;
    event.preventDefault();
    c.run();
  });

  window.teachConsole = {
    drawn,
    pointOf,
    mode: () => mode,
    candidate: () => candidate,
    state: () => state,
  };

  buildControls();
  connect();
})();
