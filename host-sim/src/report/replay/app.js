// Parapet replay page (host-sim/src/report/replay/): the data of <script id="data"> drawn with
// three.js (the global THREE of the previous script). Frame: ENU, z up, as trajectory.csv.
(function () {
  "use strict";
  var D = JSON.parse(document.getElementById("data").textContent);
  var S = D.s;
  var N = S.t.length;
  var $ = function (id) { return document.getElementById(id); };

  // A number with d decimals as the report files print it (the sign of -0 kept); the files'
  // non-finite texts are strings already.
  function fmt(v, d) {
    if (typeof v === "string") return v;
    if (v === null || v === undefined) return "-";
    return (v < 0 || Object.is(v, -0) ? "-" : "") + Math.abs(v).toFixed(d);
  }
  function num(v) { return typeof v === "number" ? v : NaN; }

  // ---------------------------------------------------------------- three.js scene
  var canvas = $("view");
  var renderer = null;
  try {
    renderer = new THREE.WebGLRenderer({ canvas: canvas, antialias: true, preserveDrawingBuffer: true });
    renderer.setPixelRatio(window.devicePixelRatio || 1);
  } catch (e) {
    window.__errors.push("WebGL: " + e.message);
    showBanner("This browser could not create a WebGL context: the 3D view is off (the plots and tables still work).");
  }
  var scene = new THREE.Scene();
  scene.background = new THREE.Color(0xdfe6ee);
  var camera = new THREE.PerspectiveCamera(50, 1, 0.02, 5000);
  camera.up.set(0, 0, 1);
  scene.add(new THREE.HemisphereLight(0xffffff, 0x8a8f99, 1.6));
  var sun = new THREE.DirectionalLight(0xffffff, 1.4);
  sun.position.set(-3, -5, 10);
  scene.add(sun);

  var bmin = D.bounds[0], bmax = D.bounds[1];
  var bctr = new THREE.Vector3((bmin[0] + bmax[0]) / 2, (bmin[1] + bmax[1]) / 2, (bmin[2] + bmax[2]) / 2);
  var bsize = new THREE.Vector3(bmax[0] - bmin[0], bmax[1] - bmin[1], bmax[2] - bmin[2]);
  var diag = Math.max(bsize.length(), 1);

  // Ground (z = 0) under the flight volume, a 1 m grid, and the bounds as a wire box.
  (function () {
    var gx = Math.max(bsize.x, 1), gy = Math.max(bsize.y, 1);
    var ground = new THREE.Mesh(new THREE.PlaneGeometry(gx, gy),
      new THREE.MeshStandardMaterial({ color: 0xc9cfc4, roughness: 1 }));
    ground.position.set(bctr.x, bctr.y, -0.002);
    scene.add(ground);
    var pts = [];
    for (var x = Math.ceil(bmin[0]); x <= bmax[0]; x++) pts.push(x, bmin[1], 0, x, bmax[1], 0);
    for (var y = Math.ceil(bmin[1]); y <= bmax[1]; y++) pts.push(bmin[0], y, 0, bmax[0], y, 0);
    if (pts.length <= 6 * 4000) scene.add(segments(pts, 0xa9b0a4));
    var box = new THREE.Box3(new THREE.Vector3(bmin[0], bmin[1], bmin[2]), new THREE.Vector3(bmax[0], bmax[1], bmax[2]));
    scene.add(new THREE.Box3Helper(box, 0x9aa6b5));
  })();

  function segments(flat, color) {
    var g = new THREE.BufferGeometry();
    g.setAttribute("position", new THREE.Float32BufferAttribute(flat, 3));
    return new THREE.LineSegments(g, new THREE.LineBasicMaterial({ color: color }));
  }
  function polyline(points, material) {
    var g = new THREE.BufferGeometry();
    g.setAttribute("position", new THREE.Float32BufferAttribute(points, 3));
    return new THREE.Line(g, material);
  }

  // Obstacles, as the scene file has them (ENU); moving ones follow their motion.
  var obstacleMat = new THREE.MeshStandardMaterial({ color: 0x8c9db3, roughness: 0.85, transparent: true, opacity: 0.72 });
  var movingMat = new THREE.MeshStandardMaterial({ color: 0xb38cb0, roughness: 0.85, transparent: true, opacity: 0.72 });
  // Unmapped obstacles (`mapped = false`: in the world, not in the map the path was planned on).
  var unmappedMat = new THREE.MeshStandardMaterial({ color: 0xe6d23c, roughness: 0.85, transparent: true, opacity: 0.72 });
  var activeMat = new THREE.MeshStandardMaterial({ color: 0xff7a1a, roughness: 0.6, emissive: 0x802000 });
  var edgeMat = new THREE.LineBasicMaterial({ color: 0x4d5a6b });
  var obstacleMeshes = [];
  var obstacleGroup = new THREE.Group();
  scene.add(obstacleGroup);
  D.obstacles.forEach(function (o, i) {
    var geo, pos;
    if (o.kind === "box") {
      geo = new THREE.BoxGeometry(Math.max(o.max[0] - o.min[0], 1e-3), Math.max(o.max[1] - o.min[1], 1e-3), Math.max(o.max[2] - o.min[2], 1e-3));
      pos = [(o.min[0] + o.max[0]) / 2, (o.min[1] + o.max[1]) / 2, (o.min[2] + o.max[2]) / 2];
    } else if (o.kind === "cylinder") {
      geo = new THREE.CylinderGeometry(o.radius, o.radius, Math.max(o.height, 1e-3), 28);
      geo.rotateX(Math.PI / 2); // three's cylinders stand on y; the scene's on z (up)
      pos = [o.base[0], o.base[1], o.base[2] + o.height / 2];
    } else if (o.kind === "sphere") {
      geo = new THREE.SphereGeometry(Math.max(o.radius, 1e-3), 24, 16);
      pos = o.center.slice();
    } else {
      geo = new THREE.SphereGeometry(0.03, 8, 6);
      pos = o.center.slice();
    }
    var moving = !!(o.velocity || o.waypoints);
    var unmapped = o.mapped === false;
    var mesh = new THREE.Mesh(geo, moving ? movingMat : unmapped ? unmappedMat : obstacleMat);
    mesh.position.set(pos[0], pos[1], pos[2]);
    mesh.userData = { obstacle: i, home: pos, moving: moving, unmapped: unmapped, baseMat: mesh.material };
    if (D.obstacles.length <= 3000) mesh.add(new THREE.LineSegments(new THREE.EdgesGeometry(geo), edgeMat));
    obstacleGroup.add(mesh);
    obstacleMeshes.push(mesh);
  });

  // Where a moving obstacle's reference point is at t (the simulator's rule: constant velocity
  // from t = 0, or piecewise-linear waypoints held outside their span); its offset from home.
  function obstacleOffset(o, t) {
    if (o.velocity) return [o.velocity[0] * t, o.velocity[1] * t, o.velocity[2] * t];
    var w = o.waypoints, p;
    if (!w || w.length === 0) return [0, 0, 0];
    if (t <= w[0][0] || w.length === 1) p = w[0];
    else if (t >= w[w.length - 1][0]) p = w[w.length - 1];
    else {
      for (var k = 0; k + 1 < w.length; k++) {
        if (t >= w[k][0] && t < w[k + 1][0]) {
          var a = (t - w[k][0]) / (w[k + 1][0] - w[k][0]);
          p = [0, w[k][1] + a * (w[k + 1][1] - w[k][1]), w[k][2] + a * (w[k + 1][2] - w[k][2]), w[k][3] + a * (w[k + 1][3] - w[k][3])];
          break;
        }
      }
      if (!p) p = w[w.length - 1];
    }
    return [p[1] - o.r[0], p[2] - o.r[1], p[3] - o.r[2]];
  }

  // Start (green) and goal (red).
  function marker(p, color, r) {
    var m = new THREE.Mesh(new THREE.SphereGeometry(r, 16, 12), new THREE.MeshStandardMaterial({ color: color }));
    m.position.set(p[0], p[1], p[2]);
    scene.add(m);
    return m;
  }
  marker(D.start, 0x1f9d3a, 0.07);
  marker(D.goal, 0xd62728, 0.07);

  // Planned path (green), reference (dashed grey), flown track coloured by speed.
  if (D.path.length > 1) {
    var pp = [];
    D.path.forEach(function (p) { pp.push(p[0], p[1], p[2]); });
    scene.add(polyline(pp, new THREE.LineBasicMaterial({ color: 0x1f9d3a })));
  }
  var vmax = 0;
  for (var k = 0; k < N; k++) vmax = Math.max(vmax, num(S.v[k]) || 0);
  function speedColor(v) {
    // Blue (slow) → green → yellow → red (fast), v / vmax.
    var a = vmax > 0 ? Math.min(Math.max(v / vmax, 0), 1) : 0;
    var c = new THREE.Color();
    c.setHSL((1 - a) * 0.66, 0.9, 0.45);
    return c;
  }
  if (N > 1) {
    var rp = [], fp = [], col = [];
    // Non-finite values (a diverged run's "NaN" texts) are left out of the lines.
    var finite3 = function (a, b, c) { return isFinite(a) && isFinite(b) && isFinite(c); };
    for (var i = 0; i < N; i++) {
      if (finite3(num(S.rx[i]), num(S.ry[i]), num(S.rz[i]))) rp.push(num(S.rx[i]), num(S.ry[i]), num(S.rz[i]));
      if (!finite3(num(S.x[i]), num(S.y[i]), num(S.z[i]))) continue;
      fp.push(num(S.x[i]), num(S.y[i]), num(S.z[i]));
      var c = speedColor(num(S.v[i]) || 0);
      col.push(c.r, c.g, c.b);
    }
    var ref = polyline(rp, new THREE.LineDashedMaterial({ color: 0x666666, dashSize: 0.08, gapSize: 0.06 }));
    ref.computeLineDistances();
    scene.add(ref);
    var flown = polyline(fp, new THREE.LineBasicMaterial({ vertexColors: true }));
    flown.geometry.setAttribute("color", new THREE.Float32BufferAttribute(col, 3));
    scene.add(flown);
  }
  if (D.collision_t !== null && N > 0) {
    var kc = sampleAt(num(D.collision_t));
    if (isFinite(num(S.x[kc])) && isFinite(num(S.y[kc])) && isFinite(num(S.z[kc]))) {
      marker([num(S.x[kc]), num(S.y[kc]), num(S.z[kc])], 0xff0000, Math.max(D.hull * 0.4, 0.04)).material.wireframe = true;
    }
  }

  // The vehicle: built in body FRD (x forward, y right, z down), turned by its attitude.
  var vehicle = new THREE.Group();
  vehicle.name = "vehicle";
  var body = new THREE.Group();
  vehicle.add(body);
  (function () {
    var arm = Math.max(D.arm, 0.02), a = arm / Math.SQRT2;
    var armMat = new THREE.MeshStandardMaterial({ color: 0x333333 });
    [[1, 1], [1, -1]].forEach(function (s) {
      var bar = new THREE.Mesh(new THREE.BoxGeometry(2 * arm, 0.015, 0.01), armMat);
      bar.rotation.z = Math.atan2(s[1], s[0]);
      body.add(bar);
    });
    // PX4 order: 1 front-right, 2 rear-left (CCW, blue), 3 front-left, 4 rear-right (CW, grey).
    [[a, a, 0x3060c0], [-a, -a, 0x3060c0], [a, -a, 0x888888], [-a, a, 0x888888]].forEach(function (r) {
      var disc = new THREE.Mesh(new THREE.CylinderGeometry(arm * 0.45, arm * 0.45, 0.008, 20),
        new THREE.MeshStandardMaterial({ color: r[2], transparent: true, opacity: 0.7 }));
      disc.rotation.x = Math.PI / 2;
      disc.position.set(r[0], r[1], -0.02);
      body.add(disc);
    });
    var nose = new THREE.Mesh(new THREE.ConeGeometry(0.025, 0.08, 10), new THREE.MeshStandardMaterial({ color: 0xd62728 }));
    nose.rotation.z = -Math.PI / 2; // cone along +x (forward)
    nose.position.set(arm * 0.55, 0, 0);
    body.add(nose);
    body.add(new THREE.Mesh(new THREE.BoxGeometry(0.06, 0.05, 0.03), armMat));
  })();
  var regionColors = [0x9aa0a6, 0x9aa0a6, 0x2ca02c, 0xff7f0e, 0xd62728];
  var hullMat = new THREE.MeshBasicMaterial({ color: 0x9aa0a6, wireframe: true, transparent: true, opacity: 0.35 });
  var hull = new THREE.Mesh(new THREE.SphereGeometry(Math.max(D.hull, 0.01), 20, 12), hullMat);
  vehicle.add(hull);
  scene.add(vehicle);
  vehicle.visible = N > 0;
  // A drop line from the vehicle to the ground: where it is, seen from afar.
  var drop = polyline([0, 0, 0, 0, 0, 0], new THREE.LineBasicMaterial({ color: 0xd62728 }));
  drop.visible = N > 0;
  scene.add(drop);

  var m4 = new THREE.Matrix4();
  // Body FRD → world ENU: T · R(yaw, pitch, roll) with R = Rz Ry Rx (FRD → NED) and T the
  // NED → ENU swap (x ↔ y, z → −z).
  function setAttitude(roll, pitch, yaw) {
    var cf = Math.cos(roll), sf = Math.sin(roll), ct = Math.cos(pitch), st = Math.sin(pitch), cp = Math.cos(yaw), sp = Math.sin(yaw);
    var r0 = [ct * cp, sf * st * cp - cf * sp, cf * st * cp + sf * sp];
    var r1 = [ct * sp, sf * st * sp + cf * cp, cf * st * sp - sf * cp];
    var r2 = [-st, sf * ct, cf * ct];
    m4.set(r1[0], r1[1], r1[2], 0, r0[0], r0[1], r0[2], 0, -r2[0], -r2[1], -r2[2], 0, 0, 0, 0, 1);
    body.quaternion.setFromRotationMatrix(m4);
  }

  // ---------------------------------------------------------------- range returns
  // Per sensor, the latest shown scan at or before the time (D.scans.shown is in scan order,
  // i.e. by time); its drawn returns (every stride-th) as one point cloud, magenta.
  var SC = D.scans, scanBySensor = [];
  SC.shown.forEach(function (sc, i) { (scanBySensor[sc[1]] = scanBySensor[sc[1]] || []).push(i); });
  var maxPts = 0;
  scanBySensor.forEach(function (l) { var m = 0; l.forEach(function (i) { m = Math.max(m, SC.shown[i][3].length / 3); }); maxPts += m; });
  var returnsGeo = new THREE.BufferGeometry();
  returnsGeo.setAttribute("position", new THREE.Float32BufferAttribute(new Float32Array(Math.max(maxPts, 1) * 3), 3));
  returnsGeo.setDrawRange(0, 0);
  var returns = new THREE.Points(returnsGeo, new THREE.PointsMaterial({ color: 0xd0208a, size: 3, sizeAttenuation: false }));
  returns.name = "returns";
  returns.frustumCulled = false;
  scene.add(returns);
  var returnsShown = [];
  function latestScan(list, t) {
    var lo = 0, hi = list.length - 1, best = -1;
    while (lo <= hi) {
      var mid = (lo + hi) >> 1;
      if (num(SC.shown[list[mid]][0]) <= t) { best = list[mid]; lo = mid + 1; } else hi = mid - 1;
    }
    return best;
  }
  function showReturns(t) {
    var pos = returnsGeo.attributes.position, n = 0;
    returnsShown = [];
    scanBySensor.forEach(function (list, sensor) {
      var i = latestScan(list, t);
      if (i < 0) return;
      var sc = SC.shown[i], p = sc[3];
      for (var q = 0; q + 2 < p.length; q += 3) pos.setXYZ(n++, num(p[q]), num(p[q + 1]), num(p[q + 2]));
      returnsShown.push({ sensor: SC.sensors[sensor] || String(sensor), t: fmt(sc[0], 4), hits: sc[2], drawn: p.length / 3 });
    });
    pos.needsUpdate = true;
    returnsGeo.setDrawRange(0, n);
    if (nowRows["returns drawn"]) nowRows["returns drawn"].textContent = SC.shown.length ? String(n) + " (1 in " + SC.stride + " of the scan)" : "-";
  }

  // ---------------------------------------------------------------- obstacle points given to the filter
  // The latest shown logged step at or before the time: its points as cyan dots.
  var FP = D.filter_points, maxFp = 1;
  FP.shown.forEach(function (st) { maxFp = Math.max(maxFp, st[1].length / 3); });
  var fpGeo = new THREE.BufferGeometry();
  fpGeo.setAttribute("position", new THREE.Float32BufferAttribute(new Float32Array(maxFp * 3), 3));
  fpGeo.setDrawRange(0, 0);
  var fpCloud = new THREE.Points(fpGeo, new THREE.PointsMaterial({ color: 0x00a6c8, size: 7, sizeAttenuation: false }));
  fpCloud.name = "filter_points";
  fpCloud.frustumCulled = false;
  scene.add(fpCloud);
  var fpShownT = null;
  function showFilterPoints(t) {
    var lo = 0, hi = FP.shown.length - 1, best = -1, n = 0, pos = fpGeo.attributes.position;
    while (lo <= hi) {
      var mid = (lo + hi) >> 1;
      if (num(FP.shown[mid][0]) <= t) { best = mid; lo = mid + 1; } else hi = mid - 1;
    }
    fpShownT = best < 0 ? null : fmt(FP.shown[best][0], 4);
    if (best >= 0) {
      var p = FP.shown[best][1];
      for (var q = 0; q + 2 < p.length; q += 3) pos.setXYZ(n++, num(p[q]), num(p[q + 1]), num(p[q + 2]));
    }
    pos.needsUpdate = true;
    fpGeo.setDrawRange(0, n);
    if (nowRows["filter's points"]) nowRows["filter's points"].textContent = best < 0 ? "-" : n + " (logged at " + fpShownT + " s)";
  }

  // ---------------------------------------------------------------- camera control
  // One spherical rig (azimuth, elevation, distance) about a target: "follow" keeps the target on
  // the vehicle, "orbit" leaves it where it is (drag: turn; shift/right drag: pan; wheel: zoom).
  var rig = { az: -Math.PI / 2 - 0.6, el: 0.55, dist: 2.2, target: new THREE.Vector3().copy(bctr), mode: "follow" };
  function placeCamera() {
    var ce = Math.cos(rig.el);
    camera.position.set(rig.target.x + rig.dist * ce * Math.cos(rig.az), rig.target.y + rig.dist * ce * Math.sin(rig.az), rig.target.z + rig.dist * Math.sin(rig.el));
    camera.lookAt(rig.target);
  }
  function setCamMode(mode) {
    rig.mode = mode;
    $("cam").value = mode;
    if (mode === "orbit") {
      rig.target.copy(bctr);
      rig.dist = diag * 0.85;
      rig.el = 0.9;
    } else {
      rig.dist = Math.max(6 * D.hull, 1.6);
      rig.el = 0.5;
    }
    update(true);
  }
  (function () {
    var drag = null;
    canvas.addEventListener("contextmenu", function (e) { e.preventDefault(); });
    canvas.addEventListener("pointerdown", function (e) {
      drag = { x: e.clientX, y: e.clientY, pan: e.button === 2 || e.shiftKey };
      canvas.setPointerCapture(e.pointerId);
    });
    canvas.addEventListener("pointerup", function () { drag = null; });
    canvas.addEventListener("pointermove", function (e) {
      if (!drag) return;
      var dx = e.clientX - drag.x, dy = e.clientY - drag.y;
      drag.x = e.clientX; drag.y = e.clientY;
      if (drag.pan && rig.mode === "orbit") {
        var s = rig.dist / Math.max(canvas.clientHeight, 1);
        var right = new THREE.Vector3(-Math.sin(rig.az), Math.cos(rig.az), 0);
        var fwd = new THREE.Vector3(Math.cos(rig.az), Math.sin(rig.az), 0);
        rig.target.addScaledVector(right, dx * s).addScaledVector(fwd, dy * s);
      } else {
        rig.az -= dx * 0.006;
        rig.el = Math.min(Math.max(rig.el + dy * 0.006, -0.2), 1.55);
      }
      update(true);
    });
    canvas.addEventListener("wheel", function (e) {
      e.preventDefault();
      rig.dist = Math.min(Math.max(rig.dist * Math.exp(e.deltaY * 0.001), 0.2), diag * 4);
      update(true);
    }, { passive: false });
  })();

  // ---------------------------------------------------------------- time and playback
  var state = { k: 0, time: N > 0 ? num(S.t[0]) : 0, playing: false, rate: 1, last: null };
  function sampleAt(t) {
    // Last displayed sample with t_k ≤ t (the first one before it).
    var lo = 0, hi = N - 1;
    if (N === 0) return 0;
    if (!(t >= num(S.t[0]))) return 0;
    while (lo < hi) {
      var mid = (lo + hi + 1) >> 1;
      if (num(S.t[mid]) <= t) lo = mid; else hi = mid - 1;
    }
    return lo;
  }
  var slider = $("slider");
  slider.max = String(Math.max(N - 1, 0));
  slider.addEventListener("input", function () { seekIndex(parseInt(slider.value, 10) || 0); });
  $("play").addEventListener("click", togglePlay);
  $("rate").addEventListener("change", function () { state.rate = parseFloat($("rate").value) || 1; });
  $("cam").addEventListener("change", function () { setCamMode($("cam").value); });
  document.addEventListener("keydown", function (e) {
    if (e.code === "Space" && e.target === document.body) { e.preventDefault(); togglePlay(); }
  });
  function togglePlay() {
    if (N === 0) return;
    if (!state.playing && state.k >= N - 1) seekIndex(0);
    state.playing = !state.playing;
    state.last = null;
    $("play").textContent = state.playing ? "❚❚" : "▶";
  }
  function seekIndex(k) {
    state.k = Math.min(Math.max(k, 0), Math.max(N - 1, 0));
    state.time = N > 0 ? num(S.t[state.k]) : 0;
    update(true);
  }
  function seekTime(t) {
    state.time = t;
    state.k = sampleAt(t);
    update(true);
  }

  // ---------------------------------------------------------------- side panel
  var nowRows = {};
  ["t [s]", "x, y, z [m]", "clearance [m]", "h̄ [m²]", "region", "filter", "barriers enforced", "active obstacle", "mode", "flight mode", "filter's points", "returns drawn"].forEach(function (name) {
    var tr = document.createElement("tr");
    var a = document.createElement("td"), b = document.createElement("td");
    a.textContent = name;
    tr.appendChild(a); tr.appendChild(b);
    $("now").appendChild(tr);
    nowRows[name] = b;
  });
  D.summary.forEach(function (p) {
    var tr = document.createElement("tr");
    var a = document.createElement("td"), b = document.createElement("td");
    a.textContent = p[0]; b.textContent = p[1];
    tr.appendChild(a); tr.appendChild(b);
    $("summary").appendChild(tr);
  });
  // A clickable list entry: seeks to its time.
  function entry(list, t, text) {
    var div = document.createElement("div");
    div.textContent = fmt(t, 4) + " s  " + text;
    div.addEventListener("click", function () { seekTime(num(t)); });
    $(list).appendChild(div);
  }
  // Guidance and flight-mode changes, in time order.
  var changes = D.mode_changes.map(function (mc) { return [mc[0], "guidance " + D.modes[mc[1]]]; })
    .concat(D.flight_mode_changes.map(function (mc) { return [mc[0], "flight mode " + D.flight_modes[mc[1]]]; }));
  changes.sort(function (a, b) { return num(a[0]) - num(b[0]); });
  changes.forEach(function (c) { entry("modes", c[0], c[1]); });
  if (D.mode_changes_cut || D.flight_mode_changes_cut) $("modes").appendChild(document.createTextNode("… (list cut)"));
  D.events.forEach(function (e) { entry("events", e[0], e[1]); });
  if (D.events_cut) $("events").appendChild(document.createTextNode("… (list cut)"));
  D.interventions.forEach(function (iv) {
    entry("barriers", iv[0], "– " + fmt(iv[1], 4) + " s: up to " + iv[2] + " barrier" + (iv[2] === 1 ? "" : "s") +
      (iv[3].length ? ", obstacle" + (iv[3].length > 1 ? "s " : " ") + iv[3].join(", ") : ""));
  });
  if (D.interventions_cut) $("barriers").appendChild(document.createTextNode("… (list cut)"));
  if (D.interventions.length === 0) $("barriers").textContent = "The filter never changed u*.";
  $("title").textContent = D.scene + " — " + D.filter + " — " + D.end_reason;
  $("note").textContent = "Drawn: " + N + " of " + D.n_samples + " samples (decimated for display; the texts are trajectory.csv's digits of the sample shown). " +
    "Planned path green, reference dashed grey, flown track coloured by speed; hull coloured by the filter's region (grey far, green nominal safe, orange filtering, red fault); obstacle the filter acts on in orange; moving obstacles violet; unmapped obstacles (not in the planned-on map) yellow. " +
    (D.scans.shown.length ? "Range returns magenta: each sensor's latest scan shown (" + D.scans.shown.length + " of " + D.scans.n_scans + " scans kept, every " + D.scans.stride + ". return drawn; ranges.csv has them all). " : "") +
    "Obstacle points given to the filter cyan (the latest of " + FP.shown.length + " of " + FP.n_steps + " logged steps, filter_points.csv). " +
    "Plots: filter interventions shaded orange, mode changes dashed grey, events dashed red." +
    (D.interventions_cut ? " Intervention list cut at its first entries." : "");
  $("legend").innerHTML = "speed 0<span class=\"bar\" style=\"background:linear-gradient(90deg,hsl(238,90%,45%),hsl(119,90%,45%),hsl(0,90%,45%))\"></span>" +
    vmax.toFixed(2) + " m/s <i style=\"background:#1f9d3a\"></i>planned <i style=\"background:#666\"></i>reference";
  if (N === 0) showBanner("This run has no trajectory samples (it ended at once): there is nothing to replay. The scene is shown as flown.");
  function showBanner(text) { var b = $("banner"); b.textContent = text; b.hidden = false; }

  // ---------------------------------------------------------------- plots
  var plots = [
    { id: "plot-speed", title: "speed |v| [m/s]", col: S.v, zero: false },
    { id: "plot-clearance", title: "clearance [m]", col: S.c, zero: true },
    { id: "plot-hbar", title: "h̄ [m²]", col: S.h, zero: true }
  ];
  var t0 = N > 0 ? num(S.t[0]) : 0, t1 = N > 0 ? num(S.t[N - 1]) : 1;
  if (!(t1 > t0)) t1 = t0 + 1;
  plots.forEach(function (p) {
    var lo = Infinity, hi = -Infinity;
    for (var i = 0; i < N; i++) { var v = num(p.col[i]); if (isFinite(v)) { lo = Math.min(lo, v); hi = Math.max(hi, v); } }
    if (!isFinite(lo)) { lo = 0; hi = 1; }
    if (p.zero) { lo = Math.min(lo, 0); hi = Math.max(hi, 0); }
    if (hi - lo < 1e-9) { hi = lo + 1; }
    p.lo = lo; p.hi = hi;
    p.canvas = $(p.id);
    var seek = function (e) {
      var r = p.canvas.getBoundingClientRect();
      var f = (e.clientX - r.left - 40) / Math.max(r.width - 48, 1);
      seekTime(t0 + Math.min(Math.max(f, 0), 1) * (t1 - t0));
    };
    p.canvas.addEventListener("pointerdown", function (e) { p.down = true; seek(e); });
    p.canvas.addEventListener("pointermove", function (e) { if (p.down) seek(e); });
    p.canvas.addEventListener("pointerup", function () { p.down = false; });
  });
  function drawPlot(p) {
    var cv = p.canvas, dpr = window.devicePixelRatio || 1;
    var w = cv.clientWidth, h = cv.clientHeight;
    if (cv.width !== Math.round(w * dpr) || cv.height !== Math.round(h * dpr)) { cv.width = Math.round(w * dpr); cv.height = Math.round(h * dpr); }
    var g = cv.getContext("2d");
    g.setTransform(dpr, 0, 0, dpr, 0, 0);
    g.clearRect(0, 0, w, h);
    var L = 40, R = 8, T = 16, B = 16, pw = Math.max(w - L - R, 1), ph = Math.max(h - T - B, 1);
    var X = function (t) { return L + (t - t0) / (t1 - t0) * pw; };
    var Y = function (v) { return T + (1 - (v - p.lo) / (p.hi - p.lo)) * ph; };
    g.fillStyle = "rgba(255,127,14,0.18)";
    D.interventions.forEach(function (iv) { var a = X(num(iv[0])), b = X(num(iv[1])); g.fillRect(a, T, Math.max(b - a, 1), ph); });
    g.strokeStyle = "#bbb"; g.lineWidth = 1;
    g.strokeRect(L, T, pw, ph);
    if (p.zero) { g.beginPath(); g.moveTo(L, Y(0)); g.lineTo(L + pw, Y(0)); g.stroke(); }
    g.setLineDash([3, 3]); g.strokeStyle = "#99a";
    D.mode_changes.forEach(function (mc, i) { if (i > 0) { var x = X(num(mc[0])); g.beginPath(); g.moveTo(x, T); g.lineTo(x, T + ph); g.stroke(); } });
    g.strokeStyle = "#d62728";
    D.events.forEach(function (e) { var x = X(num(e[0])); g.beginPath(); g.moveTo(x, T); g.lineTo(x, T + ph); g.stroke(); });
    g.setLineDash([]);
    g.strokeStyle = "#1f5fbf"; g.beginPath();
    var pen = false;
    for (var i = 0; i < N; i++) {
      var v = num(p.col[i]);
      if (!isFinite(v)) { pen = false; continue; }
      if (pen) g.lineTo(X(num(S.t[i])), Y(v)); else g.moveTo(X(num(S.t[i])), Y(v));
      pen = true;
    }
    g.stroke();
    g.fillStyle = "#333"; g.font = "11px system-ui, sans-serif";
    g.fillText(p.title, L + 4, 12);
    g.fillText(p.hi.toPrecision(3), 2, T + 9);
    g.fillText(p.lo.toPrecision(3), 2, T + ph);
    g.fillText(t0.toFixed(1) + " s", L, h - 3);
    g.fillText(t1.toFixed(1) + " s", L + pw - 34, h - 3);
    if (N > 0) {
      var xc = X(num(S.t[state.k]));
      g.strokeStyle = "#d62728"; g.lineWidth = 1.5;
      g.beginPath(); g.moveTo(xc, T); g.lineTo(xc, T + ph); g.stroke();
    }
  }

  // ---------------------------------------------------------------- update and render
  var shownK = -1, activeMesh = null;
  // Set (to the asked time, or null) once the page was opened with #t=… or #probe: the probe
  // is then rewritten at every frame of a playback (#…&play), so a dump shows the last one.
  var probing;
  function update(force) {
    var k = state.k;
    var t = N > 0 ? num(S.t[k]) : 0;
    if (force || k !== shownK) {
      shownK = k;
      slider.value = String(k);
      if (N > 0) {
        var ok = isFinite(num(S.x[k])) && isFinite(num(S.y[k])) && isFinite(num(S.z[k]));
        vehicle.visible = drop.visible = ok;
        if (ok) vehicle.position.set(num(S.x[k]), num(S.y[k]), num(S.z[k]));
        var dp = drop.geometry.attributes.position;
        dp.setXYZ(0, vehicle.position.x, vehicle.position.y, vehicle.position.z - D.hull);
        dp.setXYZ(1, vehicle.position.x, vehicle.position.y, 0);
        dp.needsUpdate = true;
        drop.geometry.computeBoundingSphere();
        setAttitude(num(S.roll[k]), num(S.pitch[k]), num(S.yaw[k]));
        hullMat.color.setHex(regionColors[S.g[k]] || 0x9aa0a6);
        $("t-val").textContent = fmt(S.t[k], 4);
        nowRows["t [s]"].textContent = fmt(S.t[k], 4);
        nowRows["x, y, z [m]"].textContent = fmt(S.x[k], 4) + ", " + fmt(S.y[k], 4) + ", " + fmt(S.z[k], 4);
        nowRows["clearance [m]"].textContent = fmt(S.c[k], 4);
        nowRows["h̄ [m²]"].textContent = fmt(S.h[k], 5);
        nowRows["region"].textContent = D.regions[S.g[k]];
        nowRows["filter"].textContent = S.f[k] ? "intervened" : "passed u*";
        var a = S.a[k];
        nowRows["active obstacle"].textContent = a < 0 ? "-" : (D.act_is_index && D.obstacles[a] && D.obstacles[a].name ? a + " (" + D.obstacles[a].name + ")" : String(a));
        nowRows["mode"].textContent = D.modes[S.m[k]];
        nowRows["flight mode"].textContent = D.flight_modes[S.fm[k]];
        nowRows["barriers enforced"].textContent = String(S.n[k]);
        if (activeMesh) { activeMesh.material = activeMesh.userData.baseMat; activeMesh = null; }
        if (D.act_is_index && a >= 0 && a < obstacleMeshes.length && S.f[k]) {
          activeMesh = obstacleMeshes[a];
          activeMesh.material = activeMat;
        }
      }
      showReturns(t);
      showFilterPoints(t);
      obstacleMeshes.forEach(function (m) {
        if (!m.userData.moving) return;
        var off = obstacleOffset(D.obstacles[m.userData.obstacle], t), h = m.userData.home;
        m.position.set(h[0] + off[0], h[1] + off[1], h[2] + off[2]);
      });
      plots.forEach(drawPlot);
    }
    if (rig.mode === "follow" && N > 0) rig.target.copy(vehicle.position);
    placeCamera();
    render();
    if (probing !== undefined && state.playing) writeProbe(probing);
  }
  function resize() {
    var w = Math.max(canvas.clientWidth, 1), h = Math.max(canvas.clientHeight, 1);
    if (renderer) renderer.setSize(w, h, false);
    camera.aspect = w / h;
    camera.updateProjectionMatrix();
    plots.forEach(drawPlot);
  }
  function render() { if (renderer) renderer.render(scene, camera); }
  window.addEventListener("resize", function () { resize(); update(true); });

  function frame(now) {
    if (state.playing && N > 0) {
      if (state.last !== null) {
        state.time += (now - state.last) / 1000 * state.rate;
        if (state.time >= num(S.t[N - 1])) { state.time = num(S.t[N - 1]); state.playing = false; $("play").textContent = "▶"; }
        var k = sampleAt(state.time);
        if (k !== state.k) { state.k = k; update(false); }
        else if (rig.mode === "follow") { update(false); }
      }
      state.last = now;
    }
    requestAnimationFrame(frame);
  }

  // ---------------------------------------------------------------- #t=… and the probe
  function hashParams() {
    var out = {};
    location.hash.replace(/^#/, "").split("&").forEach(function (kv) {
      var i = kv.indexOf("=");
      if (kv) out[i < 0 ? kv : kv.slice(0, i)] = i < 0 ? "" : decodeURIComponent(kv.slice(i + 1));
    });
    return out;
  }
  function fromHash() {
    var h = hashParams();
    if (h.cam === "orbit" || h.cam === "follow") setCamMode(h.cam);
    if (h.rate && ["0.25", "0.5", "1", "2", "4", "8", "16"].indexOf(h.rate) >= 0) { $("rate").value = h.rate; state.rate = parseFloat(h.rate); }
    if (h.t !== undefined) {
      var t = parseFloat(h.t);
      seekTime(isFinite(t) ? t : 0);
      probing = isFinite(t) ? t : null;
      writeProbe(probing);
    } else if ("probe" in h) {
      probing = null;
      writeProbe(null);
    }
    if ("play" in h && !state.playing) togglePlay();
  }
  function writeProbe(requested) {
    var p = { requested_t: isFinite(requested) ? requested : null, empty: N === 0, webgl: !!renderer, errors: [] };
    try {
      vehicle.updateMatrixWorld(true);
      camera.updateMatrixWorld(true);
      var count = 0;
      scene.traverse(function (o) { if (o.isMesh && o.userData && o.userData.obstacle !== undefined) count++; });
      p.obstacle_meshes = count;
      p.scene_obstacles = D.obstacles.length;
      p.unmapped_meshes = obstacleMeshes.filter(function (m) { return m.userData.unmapped; }).length;
      p.n_samples = D.n_samples;
      p.n_display = N;
      p.sample_index = N > 0 ? S.i[state.k] : null;
      p.t_shown = $("t-val").textContent;
      var now = {};
      Object.keys(nowRows).forEach(function (k) { now[k] = nowRows[k].textContent; });
      p.now = now;
      var w = vehicle.getWorldPosition(new THREE.Vector3());
      p.vehicle_world = [fmt(w.x, 4), fmt(w.y, 4), fmt(w.z, 4)];
      p.vehicle_visible = vehicle.visible;
      // The body's forward (FRD x) and down (FRD z) axes in the world (ENU), as drawn.
      var q = body.getWorldQuaternion(new THREE.Quaternion());
      var fwd = new THREE.Vector3(1, 0, 0).applyQuaternion(q), down = new THREE.Vector3(0, 0, 1).applyQuaternion(q);
      p.body_forward = [fwd.x, fwd.y, fwd.z];
      p.body_down = [down.x, down.y, down.z];
      var s = w.clone().project(camera);
      var cw = canvas.clientWidth, ch = canvas.clientHeight;
      p.canvas = [cw, ch];
      p.screen = [(s.x + 1) / 2 * cw, (1 - s.y) / 2 * ch];
      p.on_screen = Math.abs(s.x) <= 1 && Math.abs(s.y) <= 1 && s.z > -1 && s.z < 1;
      // Moving obstacles where the scene graph has them: [index, centre x, y, z] (mesh origin:
      // box and sphere centre, cylinder axis midpoint).
      p.moving = obstacleMeshes.filter(function (m) { return m.userData.moving; }).map(function (m) {
        var c = m.getWorldPosition(new THREE.Vector3());
        return [m.userData.obstacle, c.x, c.y, c.z];
      });
      p.returns_drawn = returnsGeo.drawRange.count;
      p.filter_points_drawn = fpGeo.drawRange.count;
      p.filter_points_t = fpShownT;
      p.returns_scans = returnsShown;
      p.returns_stride = SC.stride;
      p.events_shown = Array.prototype.map.call($("events").children, function (d) { return d.textContent; });
      p.modes_shown = Array.prototype.map.call($("modes").children, function (d) { return d.textContent; });
      p.barriers_shown = Array.prototype.map.call($("barriers").children, function (d) { return d.textContent; });
      p.summary_shown = Array.prototype.map.call($("summary").rows, function (r) { return [r.cells[0].textContent, r.cells[1].textContent]; });
      p.camera = rig.mode;
      p.playing = state.playing;
      p.ready_ms = Math.round(performance.now());
    } catch (e) {
      window.__errors.push("probe: " + e.message);
    }
    p.errors = window.__errors.slice();
    var pre = $("probe");
    pre.textContent = JSON.stringify(p);
  }

  resize();
  setCamMode("follow");
  if (N === 0) setCamMode("orbit");
  window.addEventListener("hashchange", fromHash);
  fromHash();
  requestAnimationFrame(frame);
})();
