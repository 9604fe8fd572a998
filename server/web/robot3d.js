// The 3D view of a URDF robot's job, in the manner of Drake's MeshCat and MuJoCo's viewer: the links in
// the world, a time slider over the trajectory, play and pause, and a running job followed as its rows are
// written. Plain JavaScript, no build step; three.js r111 (Debian's libjs-three, MIT) is compiled into the
// server and served from /ui/three.min.js and /ui/OrbitControls.js, so the page works offline.
//
// The page does no kinematics: every link's world pose comes from the server
// (GET /v1/jobs/{id}/kinematics, the model's own forward kinematics), and is put as it is into the link's
// matrix. What the page adds is only how a link looks in its own frame: the URDF's boxes, cylinders and
// spheres where it has them, otherwise capsules from the link's origin to each child's joint origin.
//
// Entry points (window.MoreauRobot3D):
//   open(container, jobId, get)  draws the job's robot into `container`; `get(path)` fetches a path of the
//                                API with the page's token and resolves to a Response (app.js's request).
//   close()                      removes the view and stops following.
//   drawnPoses()                 for tests: each link's world matrix as three.js holds it after the last
//                                render (16 numbers, column-major) and the shapes drawn in its frame, with
//                                the frame's t and row.
// Nothing the server sends is put in as HTML: names and messages are text (textContent).
'use strict';

(function () {
  const POLL_MS = 1000;       // a running job's rows are fetched again this often
  const FRAMES = 400;         // frames asked for (the server caps them: max_frames)
  const CANVAS_HEIGHT = 480;  // px; the width is the container's

  let view = null;  // the open view, or null
  let generation = 0;  // bumped by open() and close(): answers for an older view are dropped

  function text(tag, s, cls) {
    const e = document.createElement(tag);
    if (cls) e.className = cls;
    e.textContent = String(s);
    return e;
  }

  async function fetchKinematics(v, query) {
    const r = await v.get('/v1/jobs/' + encodeURIComponent(v.jobId) + '/kinematics' + query);
    return r.json();
  }

  // A pose of the answer (3 x 4, row by row) into a three.js matrix (Matrix4.set takes rows too).
  function setPose(matrix, p) {
    matrix.set(p[0], p[1], p[2], p[3], p[4], p[5], p[6], p[7], p[8], p[9], p[10], p[11], 0, 0, 0, 1);
  }

  function validPose(p) {
    return Array.isArray(p) && p.length === 12 && p.every((x) => typeof x === 'number' && Number.isFinite(x));
  }

  function validVector(v) {
    return Array.isArray(v) && v.length === 3 && v.every((x) => typeof x === 'number' && Number.isFinite(x));
  }

  // The radius of the capsules and joint balls: a fraction of the longest segment between joint origins.
  function capsuleRadius(links) {
    let longest = 0;
    for (const l of links) if (validVector(l.joint_origin)) longest = Math.max(longest, Math.hypot(...l.joint_origin));
    return Math.max(0.005, 0.12 * (longest || 0.1));
  }

  // How link `link` looks in its own frame: its primitive visuals, or capsules to its children's joint origins.
  function linkShapes(THREE, link, children, radius, material, jointMaterial) {
    const group = new THREE.Group();
    const visuals = Array.isArray(link.visuals) ? link.visuals : [];
    const Z_TO_Y = new THREE.Matrix4().makeRotationX(Math.PI / 2);  // three.js cylinders run along y, URDF's along z
    let drawn = 0;
    for (const v of visuals) {
      if (!validPose(v.origin)) continue;
      let geometry = null;
      if (v.shape === 'box' && validVector(v.size)) geometry = new THREE.BoxBufferGeometry(v.size[0], v.size[1], v.size[2]);
      else if (v.shape === 'cylinder' && v.radius >= 0 && v.length >= 0) geometry = new THREE.CylinderBufferGeometry(v.radius, v.radius, v.length, 32);
      else if (v.shape === 'sphere' && v.radius >= 0) geometry = new THREE.SphereBufferGeometry(v.radius, 32, 16);
      if (!geometry) continue;
      const mesh = new THREE.Mesh(geometry, material);
      mesh.name = v.shape;
      mesh.matrixAutoUpdate = false;
      setPose(mesh.matrix, v.origin);
      if (v.shape === 'cylinder') mesh.matrix.multiply(Z_TO_Y);
      group.add(mesh);
      ++drawn;
    }
    group.userData.shapes = group.children.map((c) => c.name);
    if (drawn > 0) return group;
    // No primitive geometry: a ball at the joint and a capsule to each child's joint origin.
    group.add(new THREE.Mesh(new THREE.SphereBufferGeometry(radius * 1.15, 24, 12), jointMaterial));
    for (const child of children) {
      if (!validVector(child.joint_origin)) continue;
      const end = new THREE.Vector3(...child.joint_origin);
      const length = end.length();
      if (!(length > 1e-9)) continue;
      const capsule = new THREE.Group();
      capsule.name = 'capsule';
      capsule.add(new THREE.Mesh(new THREE.CylinderBufferGeometry(radius, radius, length, 24), material));
      const cap = new THREE.SphereBufferGeometry(radius, 24, 12);
      const top = new THREE.Mesh(cap, material);
      top.position.y = length / 2;
      const bottom = new THREE.Mesh(cap, material);
      bottom.position.y = -length / 2;
      capsule.add(top, bottom);
      // The cylinder's axis (y) onto the segment, its centre at the segment's middle.
      capsule.quaternion.setFromUnitVectors(new THREE.Vector3(0, 1, 0), end.clone().normalize());
      capsule.position.copy(end).multiplyScalar(0.5);
      group.add(capsule);
    }
    group.userData.shapes = group.children.map((c) => c.name || 'joint');
    return group;
  }

  function buildScene(v, answer) {
    const THREE = window.THREE;
    const links = Array.isArray(answer.links) ? answer.links : [];
    const scene = new THREE.Scene();
    scene.background = new THREE.Color(0xf4f6f8);
    scene.add(new THREE.HemisphereLight(0xffffff, 0x667788, 0.9));
    const sun = new THREE.DirectionalLight(0xffffff, 0.6);
    sun.position.set(2, -3, 5);
    scene.add(sun);
    // The world: z up, as URDF has it. The ground grid in the xy plane, and the world axes (x red, y green, z blue).
    // How far the robot reaches: at most the sum of its segments (its length when stretched out).
    const reach = Math.max(0.3, links.reduce((sum, l) => sum + (validVector(l.joint_origin) ? Math.hypot(...l.joint_origin) : 0), 0));
    const gridSize = 2 * Math.ceil(reach * 1.5);
    const grid = new THREE.GridHelper(gridSize, 10 * gridSize, 0x8899aa, 0xccd3da);
    grid.rotation.x = Math.PI / 2;
    scene.add(grid);
    scene.add(new THREE.AxesHelper(0.25 * reach));

    const radius = capsuleRadius(links);
    const colours = [0xf08c00, 0x8a939c];
    const jointMaterial = new THREE.MeshLambertMaterial({ color: 0x3b4248 });
    v.linkObjects = links.map((link, i) => {
      const children = links.filter((c) => c.parent === link.name);
      const material = new THREE.MeshLambertMaterial({ color: colours[i % 2] });
      const object = linkShapes(THREE, link, children, radius, material, jointMaterial);
      object.add(new THREE.AxesHelper(radius * 2.5));  // the link frame
      object.matrixAutoUpdate = false;  // its matrix is the server's pose, and nothing else
      object.name = String(link.name);
      scene.add(object);
      return object;
    });
    v.scene = scene;

    const width = Math.max(320, v.box.clientWidth || 640);
    v.camera = new THREE.PerspectiveCamera(45, width / CANVAS_HEIGHT, 0.01 * reach, 100 * reach);
    v.camera.up.set(0, 0, 1);
    v.camera.position.set(0.9 * reach, -1.2 * reach, 0.6 * reach);
    v.renderer = new THREE.WebGLRenderer({ antialias: true, preserveDrawingBuffer: true });
    v.renderer.setPixelRatio(window.devicePixelRatio || 1);
    v.renderer.setSize(width, CANVAS_HEIGHT);
    v.canvasBox.replaceChildren(v.renderer.domElement);
    v.controls = new THREE.OrbitControls(v.camera, v.renderer.domElement);
    v.controls.target.set(0, 0, 0.05 * reach);
    v.controls.update();
    v.controls.addEventListener('change', () => render(v));
    v.onResize = () => {
      const w = Math.max(320, v.box.clientWidth || 640);
      v.camera.aspect = w / CANVAS_HEIGHT;
      v.camera.updateProjectionMatrix();
      v.renderer.setSize(w, CANVAS_HEIGHT);
      render(v);
    };
    window.addEventListener('resize', v.onResize);
  }

  function render(v) {
    if (v.renderer) v.renderer.render(v.scene, v.camera);
  }

  // Shows frame i: every link's matrix set to its pose, then drawn.
  function showFrame(v, i) {
    if (!v.frames.length) {
      v.status.textContent = v.final ? 'the job wrote no trajectory' : 'waiting for the first rows of the trajectory';
      render(v);
      return;
    }
    i = Math.max(0, Math.min(v.frames.length - 1, i));
    v.index = i;
    const frame = v.frames[i];
    const poses = Array.isArray(frame.poses) ? frame.poses : [];
    v.linkObjects.forEach((object, k) => {
      if (validPose(poses[k])) setPose(object.matrix, poses[k]);
      object.matrixWorldNeedsUpdate = true;
      object.visible = validPose(poses[k]);
    });
    v.slider.max = String(v.frames.length - 1);
    v.slider.value = String(i);
    v.time.textContent = 't = ' + Number(frame.t).toPrecision(6) + ' s (row ' + frame.row + ')';
    v.status.textContent = v.robot + ': ' + v.linkObjects.length + ' links, frame ' + (i + 1) + ' of ' + v.frames.length +
      (v.final ? '' : '; the job is ' + v.state + ': following its rows as they are written');
    v.shown = { t: frame.t, row: frame.row };
    render(v);
  }

  // Takes an answer: the frames replace the ones held (a running job's are spread over more rows each
  // time). A view at its last frame stays at the last; elsewhere it keeps the time it showed.
  function takeFrames(v, answer) {
    const atEnd = v.index >= v.frames.length - 1;
    v.frames = Array.isArray(answer.frames) ? answer.frames : [];
    v.final = answer.final === true;
    v.state = String(answer.state);
    let i = v.frames.length - 1;
    if (!atEnd && !v.playing && v.shown) {
      i = 0;
      while (i + 1 < v.frames.length && Number(v.frames[i + 1].t) <= v.shown.t) ++i;
    }
    showFrame(v, i);
  }

  function poll(v, mine) {
    if (v.final) return;
    v.timer = setTimeout(async () => {
      if (mine !== generation) return;
      try {
        const answer = await fetchKinematics(v, '?max_samples=' + FRAMES);
        if (mine !== generation) return;
        takeFrames(v, answer);
      } catch (e) {
        if (mine === generation) v.status.textContent = e.message || String(e);
      }
      if (mine === generation) poll(v, mine);
    }, POLL_MS);
  }

  // Play: the frames at the pace of simulated time (one simulated second a second), from the frame shown.
  function togglePlay(v) {
    if (!v.frames.length) return;
    v.playing = !v.playing;
    v.playButton.textContent = v.playing ? 'Pause' : 'Play';
    if (!v.playing) return;
    if (v.index >= v.frames.length - 1) showFrame(v, 0);
    const t0 = Number(v.frames[v.index].t);
    const start = performance.now();
    const step = () => {
      if (!v.playing || view !== v) return;
      const t = t0 + (performance.now() - start) / 1000;
      let i = v.index;
      while (i + 1 < v.frames.length && Number(v.frames[i + 1].t) <= t) ++i;
      if (i !== v.index) showFrame(v, i);
      if (i >= v.frames.length - 1 && v.final) {
        v.playing = false;
        v.playButton.textContent = 'Play';
        return;
      }
      v.raf = requestAnimationFrame(step);
    };
    v.raf = requestAnimationFrame(step);
  }

  function close() {
    ++generation;
    const v = view;
    view = null;
    if (!v) return;
    clearTimeout(v.timer);
    cancelAnimationFrame(v.raf);
    if (v.controls) v.controls.dispose();
    if (v.scene) {
      v.scene.traverse((o) => {
        if (o.geometry) o.geometry.dispose();
        if (o.material) o.material.dispose();
      });
    }
    if (v.renderer) {
      v.renderer.dispose();
      v.renderer.forceContextLoss();  // a browser keeps only a few WebGL contexts: give this one back now
    }
    window.removeEventListener('resize', v.onResize);
    v.box.remove();
  }

  async function open(container, jobId, get) {
    close();
    const mine = generation;
    const box = document.createElement('div');
    box.className = 'robot3d';
    const v = { jobId: String(jobId), get, box, frames: [], index: 0, final: false, playing: false, linkObjects: [], shown: null };
    v.status = text('div', 'loading the robot...', 'robot3d-status');
    v.canvasBox = document.createElement('div');
    v.canvasBox.className = 'robot3d-canvas';
    v.playButton = text('button', 'Play');
    v.playButton.type = 'button';
    v.slider = document.createElement('input');
    v.slider.type = 'range';
    v.slider.min = '0';
    v.slider.max = '0';
    v.slider.step = '1';
    v.slider.value = '0';
    v.slider.setAttribute('aria-label', 'time');
    v.time = text('span', '', 'robot3d-time');
    const closeButton = text('button', 'Close 3D view');
    closeButton.type = 'button';
    const controls = document.createElement('div');
    controls.className = 'robot3d-controls';
    controls.append(v.playButton, v.slider, v.time, closeButton);
    box.append(v.status, v.canvasBox, controls);
    container.replaceChildren(box);
    view = v;

    if (!window.THREE || !window.THREE.WebGLRenderer || !window.THREE.OrbitControls) {
      v.status.textContent = 'three.js is not built into this server (install libjs-three and rebuild moreau-server): no 3D view';
      v.status.className = 'robot3d-status error';
      return;
    }
    v.slider.addEventListener('input', () => {
      if (v.playing) togglePlay(v);
      showFrame(v, Number(v.slider.value));
    });
    v.playButton.addEventListener('click', () => togglePlay(v));
    closeButton.addEventListener('click', close);
    try {
      const answer = await fetchKinematics(v, '?max_samples=' + FRAMES);
      if (mine !== generation) return;
      v.robot = String(answer.robot || 'robot');
      buildScene(v, answer);
      takeFrames(v, answer);
      poll(v, mine);
    } catch (e) {
      if (mine !== generation) return;
      v.status.textContent = e.message || String(e);
      v.status.className = 'robot3d-status error';
    }
  }

  // For tests: what was drawn last, each link's world matrix as three.js holds it (column-major).
  function drawnPoses() {
    if (!view || !view.shown) return null;
    return {
      t: view.shown.t,
      row: view.shown.row,
      final: view.final,
      frames: view.frames.length,
      links: view.linkObjects.map((o) => ({ name: o.name, matrix: Array.from(o.matrixWorld.elements), shapes: o.userData.shapes })),
    };
  }

  window.MoreauRobot3D = Object.freeze({ open, close, drawnPoses, jobId: () => (view ? view.jobId : null) });
})();
