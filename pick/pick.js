// photomill pick: the page (issue 29). Everything the page knows is in window.pick (tests read
// it): the job's state from /api/state, the panes' views, and the guidance (epipolar curves and
// predicted positions, in image pixels, OpenCV's convention) for the current point.
'use strict';
(() => {
  const token = new URLSearchParams(location.search).get('token') || '';
  const pick = window.pick = {
    state: null, currentId: 0, refine: 'corner', active: 0, ready: false, lastMark: null, error: null,
    panes: [0, 1].map((i) => ({ index: i, photo: i, zoom: null, cx: 0, cy: 0, img: null, thumb: null, guide: null, loading: null })),
  };
  const $ = (s) => document.querySelector(s);
  const paneEls = [...document.querySelectorAll('.pane')];

  function status(text, isError) {
    const el = $('#status');
    el.textContent = text;
    el.classList.toggle('error', !!isError);
    if (isError) pick.error = text;
  }

  async function api(path, body) {
    const sep = path.includes('?') ? '&' : '?';
    const init = body === undefined ? {} : { method: 'POST', headers: { 'Content-Type': 'application/json' }, body: JSON.stringify(body) };
    const r = await fetch(path + sep + 'token=' + encodeURIComponent(token), init);
    const text = await r.text();
    if (!r.ok) throw new Error(text.trim() || r.status + ' ' + r.statusText);
    return text ? JSON.parse(text) : null;
  }
  pick.api = api;

  // --- coordinates: image pixel (u, v) has its centre at (u + 0.5, v + 0.5) of the image area
  function canvasSize(p) {
    const c = paneEls[p.index].querySelector('canvas');
    return { c, w: c.clientWidth, h: c.clientHeight };
  }
  pick.toScreen = (pane, u, v) => {
    const p = pick.panes[pane];
    const { c, w, h } = canvasSize(p);
    const r = c.getBoundingClientRect();
    return { x: r.left + (u + 0.5 - p.cx) * p.zoom + w / 2, y: r.top + (v + 0.5 - p.cy) * p.zoom + h / 2 };
  };
  pick.toImage = (pane, clientX, clientY) => {
    const p = pick.panes[pane];
    const { c, w, h } = canvasSize(p);
    const r = c.getBoundingClientRect();
    return { u: (clientX - r.left - w / 2) / p.zoom + p.cx - 0.5, v: (clientY - r.top - h / 2) / p.zoom + p.cy - 0.5 };
  };

  function photoOf(p) { return pick.state.photos[p.photo]; }

  function fit(p) {
    const ph = photoOf(p);
    const { w, h } = canvasSize(p);
    p.zoom = Math.min(w / ph.width_px, h / ph.height_px) || 0.1;
    p.cx = ph.width_px / 2;
    p.cy = ph.height_px / 2;
  }

  // Shows photo `photo` in pane `pane`; resolves once the full-size image is decoded.
  function setPhoto(pane, photo) {
    const p = pick.panes[pane];
    const changed = p.photo !== photo || !p.img;
    p.photo = photo;
    paneEls[pane].querySelector('.photo-select').value = String(photo);
    if (!changed && p.loading) return p.loading;
    p.img = null;
    p.thumb = thumbs[photo] || null;
    if (p.zoom === null || changed) fit(p);
    const img = new Image();
    img.decoding = 'async';
    p.loading = new Promise((resolve, reject) => {
      img.onload = () => { if (p.photo === photo) { p.img = img; draw(pane); } resolve(); };
      img.onerror = () => { status('cannot load photo ' + pick.state.photos[photo].name, true); reject(new Error('photo')); };
    });
    img.src = '/photo/' + photo + '?token=' + encodeURIComponent(token);
    refreshGuide(pane);
    markThumbs();
    draw(pane);
    return p.loading;
  }

  // Test and keyboard entry: photo, zoom (screen px per image px) and the image pixel to centre.
  pick.view = async (pane, photo, zoom, u, v) => {
    const wait = setPhoto(pane, photo);
    const p = pick.panes[pane];
    p.zoom = zoom;
    p.cx = u + 0.5;
    p.cy = v + 0.5;
    draw(pane);
    await wait;
    draw(pane);
  };

  // --- drawing
  function draw(pane) {
    const p = pick.panes[pane];
    if (!pick.state || p.zoom === null) return;
    const { c, w, h } = canvasSize(p);
    const dpr = window.devicePixelRatio || 1;
    if (c.width !== Math.round(w * dpr) || c.height !== Math.round(h * dpr)) {
      c.width = Math.round(w * dpr);
      c.height = Math.round(h * dpr);
    }
    const g = c.getContext('2d');
    g.setTransform(dpr, 0, 0, dpr, 0, 0);
    g.clearRect(0, 0, w, h);
    const ph = photoOf(p);
    const sx = (ax) => (ax - p.cx) * p.zoom + w / 2;
    const sy = (ay) => (ay - p.cy) * p.zoom + h / 2;
    g.imageSmoothingEnabled = p.zoom < 2;
    const src = p.img || p.thumb;
    if (src && src.complete && src.naturalWidth) g.drawImage(src, sx(0), sy(0), ph.width_px * p.zoom, ph.height_px * p.zoom);
    // Epipolar curves and the predicted position of the current point.
    if (p.guide) {
      g.lineWidth = 1.5;
      g.strokeStyle = '#3cf';
      for (const curve of p.guide.curves) {
        for (const line of curve.polylines) {
          g.beginPath();
          line.forEach(([u, v], k) => (k ? g.lineTo : g.moveTo).call(g, sx(u + 0.5), sy(v + 0.5)));
          g.stroke();
        }
      }
      if (p.guide.predicted_px) {
        const [u, v] = p.guide.predicted_px;
        g.strokeStyle = '#f3f';
        g.beginPath();
        g.arc(sx(u + 0.5), sy(v + 0.5), 9, 0, 2 * Math.PI);
        g.stroke();
      }
    }
    // Marked points.
    g.font = '12px system-ui, sans-serif';
    for (const pt of pick.state.points) {
      const o = pt.observations.find((x) => x.image === ph.name);
      if (!o) continue;
      const x = sx(o.u_px + 0.5), y = sy(o.v_px + 0.5);
      const current = pt.point_id === pick.currentId;
      g.strokeStyle = current ? '#ff0' : '#4f4';
      g.lineWidth = current ? 2 : 1.5;
      g.beginPath();
      g.moveTo(x - 8, y); g.lineTo(x - 2, y); g.moveTo(x + 2, y); g.lineTo(x + 8, y);
      g.moveTo(x, y - 8); g.lineTo(x, y - 2); g.moveTo(x, y + 2); g.lineTo(x, y + 8);
      g.stroke();
      g.fillStyle = g.strokeStyle;
      let label = String(pt.point_id);
      if (o.residual_px !== undefined) label += ' (' + o.residual_px.toFixed(2) + ' px)';
      g.fillText(label, x + 9, y - 9);
    }
    const info = paneEls[pane].querySelector('.info');
    info.textContent = ph.width_px + ' x ' + ph.height_px + ' px, zoom ' + p.zoom.toFixed(2) + (ph.oriented ? ', oriented' : '');
  }
  function drawAll() { pick.panes.forEach((p) => draw(p.index)); }
  pick.draw = drawAll;

  // --- state and guidance
  async function refreshGuide(pane) {
    const p = pick.panes[pane];
    if (!pick.state || !pick.state.oriented || !photoOf(p).oriented) { p.guide = null; return; }
    const id = pick.currentId, photo = p.photo;
    try {
      const guide = await api('/api/guide?point=' + id + '&photo=' + photo);
      if (id === pick.currentId && photo === p.photo) { p.guide = guide; draw(pane); }
    } catch (e) { status(e.message, true); }
  }
  pick.refreshGuides = () => Promise.all(pick.panes.map((p) => refreshGuide(p.index)));

  function renderPoints() {
    const body = $('#points tbody');
    body.textContent = '';
    for (const pt of pick.state.points) {
      const tr = document.createElement('tr');
      if (pt.point_id === pick.currentId) tr.className = 'current';
      const res = pt.observations.map((o) => o.residual_px).filter((r) => r !== undefined);
      const cells = [pt.point_id, pt.observations.length, res.length ? Math.max(...res).toFixed(2) : (pt.triangulation_note ? '-' : '')];
      for (const c of cells) {
        const td = document.createElement('td');
        td.textContent = String(c);
        tr.appendChild(td);
      }
      if (pt.triangulation_note) tr.title = pt.triangulation_note;
      tr.addEventListener('click', () => setCurrent(pt.point_id));
      body.appendChild(tr);
    }
  }

  async function loadState() {
    pick.state = await api('/api/state');
    renderPoints();
    drawAll();
    await pick.refreshGuides();
  }
  pick.loadState = loadState;

  function setCurrent(id) {
    pick.currentId = id;
    $('#point-id').value = String(id);
    renderPoints();
    drawAll();
    pick.refreshGuides();
  }
  pick.setCurrent = setCurrent;

  // --- actions
  async function mark(pane, u, v) {
    const p = pick.panes[pane];
    try {
      const r = await api('/api/mark', { photo: p.photo, point_id: pick.currentId, u_px: u, v_px: v, refine: pick.refine, zoom: p.zoom });
      pick.lastMark = r;
      status('point ' + r.point_id + ' in ' + r.image + ' at (' + r.u_px.toFixed(2) + ', ' + r.v_px.toFixed(2) + ')' +
             (r.refined ? ', ' + r.refine + ' moved it ' + r.shift_px.toFixed(2) + ' px' : '') + (r.note ? ': ' + r.note : ''), false);
      await loadState();
    } catch (e) { status(e.message, true); }
  }
  async function removeCurrent() {
    const p = pick.panes[pick.active];
    try {
      const r = await api('/api/delete', { photo: p.photo, point_id: pick.currentId });
      status(r.removed ? 'deleted point ' + pick.currentId + ' in ' + photoOf(p).name : 'point ' + pick.currentId + ' is not marked in ' + photoOf(p).name, false);
      await loadState();
    } catch (e) { status(e.message, true); }
  }
  async function undo() {
    try {
      const r = await api('/api/undo', {});
      status(r.undone ? 'undone' : 'nothing to undo', false);
      await loadState();
    } catch (e) { status(e.message, true); }
  }
  async function finish() {
    try {
      const r = await fetch('/api/quit?token=' + encodeURIComponent(token), { method: 'POST', headers: { 'Content-Type': 'application/json' }, body: '{}' });
      status((await r.text()).trim(), !r.ok);
      pick.finished = true;
    } catch (e) { status(e.message, true); }
  }
  function step(pane, delta) {
    const n = pick.state.photos.length;
    setPhoto(pane, (pick.panes[pane].photo + delta + n) % n);
  }

  // --- events
  paneEls.forEach((el, pane) => {
    const c = el.querySelector('canvas');
    let down = null;
    c.addEventListener('mousedown', (e) => {
      if (e.button !== 0) return;
      down = { x: e.clientX, y: e.clientY, cx: pick.panes[pane].cx, cy: pick.panes[pane].cy, moved: false };
    });
    window.addEventListener('mousemove', (e) => {
      if (!down) return;
      const p = pick.panes[pane];
      if (Math.abs(e.clientX - down.x) + Math.abs(e.clientY - down.y) > 3) down.moved = true;
      if (down.moved) {
        p.cx = down.cx - (e.clientX - down.x) / p.zoom;
        p.cy = down.cy - (e.clientY - down.y) / p.zoom;
        draw(pane);
      }
    });
    window.addEventListener('mouseup', (e) => {
      if (!down) return;
      const d = down;
      down = null;
      if (!d.moved && e.target === c) {
        const { u, v } = pick.toImage(pane, e.clientX, e.clientY);
        mark(pane, u, v);
      }
    });
    c.addEventListener('mouseenter', () => {
      pick.active = pane;
      paneEls.forEach((x, i) => x.classList.toggle('active', i === pane));
    });
    c.addEventListener('wheel', (e) => {
      e.preventDefault();
      const p = pick.panes[pane];
      const before = pick.toImage(pane, e.clientX, e.clientY);
      p.zoom = Math.min(64, Math.max(0.02, p.zoom * (e.deltaY < 0 ? 1.25 : 0.8)));
      const after = pick.toImage(pane, e.clientX, e.clientY);
      p.cx += before.u - after.u;
      p.cy += before.v - after.v;
      draw(pane);
    }, { passive: false });
    el.querySelector('.photo-select').addEventListener('change', (e) => setPhoto(pane, Number(e.target.value)));
  });
  window.addEventListener('resize', drawAll);
  window.addEventListener('keydown', (e) => {
    if (e.target instanceof HTMLInputElement || e.target instanceof HTMLSelectElement) return;
    if ((e.ctrlKey || e.metaKey) && e.key === 'z') { e.preventDefault(); undo(); }
    else if (e.key === 'n' || e.key === 'N') setCurrent(pick.state.next_free_id);
    else if (e.key === ']' || e.key === 'PageDown') step(pick.active, 1);
    else if (e.key === '[' || e.key === 'PageUp') step(pick.active, -1);
    else if (e.key === 'Delete' || e.key === 'Backspace') { e.preventDefault(); removeCurrent(); }
    else if (e.key === 'f') { fit(pick.panes[pick.active]); draw(pick.active); }
  });
  $('#point-id').addEventListener('change', (e) => {
    const id = Number(e.target.value);
    if (Number.isInteger(id) && id >= 0) setCurrent(id); else status('a point id is a whole number from 0', true);
  });
  $('#new-point').addEventListener('click', () => setCurrent(pick.state.next_free_id));
  $('#refine').addEventListener('change', (e) => { pick.refine = e.target.value; });
  $('#delete').addEventListener('click', removeCurrent);
  $('#undo').addEventListener('click', undo);
  $('#finish').addEventListener('click', finish);

  // --- start: state, thumbnails, the first two photos
  const thumbs = [];
  function markThumbs() {
    document.querySelectorAll('#thumbs img').forEach((img, i) => {
      img.classList.toggle('left', i === pick.panes[0].photo);
      img.classList.toggle('right', i === pick.panes[1].photo);
    });
  }
  (async () => {
    try {
      pick.state = await api('/api/state');
      pick.refine = pick.state.default_refine;
      $('#refine').value = pick.refine;
      const n = pick.state.photos.length;
      const strip = $('#thumbs');
      pick.state.photos.forEach((ph, i) => {
        const img = document.createElement('img');
        img.alt = ph.name;
        img.title = ph.name;
        img.src = '/thumb/' + i + '?token=' + encodeURIComponent(token);
        img.addEventListener('click', (e) => setPhoto(e.shiftKey ? 1 : 0, i));
        thumbs[i] = img;
        strip.appendChild(img);
      });
      paneEls.forEach((el) => {
        const sel = el.querySelector('.photo-select');
        pick.state.photos.forEach((ph, i) => sel.add(new Option(ph.name, String(i))));
      });
      setCurrent(pick.state.next_free_id);
      await Promise.all([setPhoto(0, 0), setPhoto(1, Math.min(1, n - 1))]);
      renderPoints();
      drawAll();
      pick.ready = true;
      status(n + ' photos' + (pick.state.oriented ? ', oriented' : '') + '; marks are saved to ' + pick.state.observations_file, false);
    } catch (e) { status(e.message, true); }
  })();
})();
