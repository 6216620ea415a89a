// The headset console (WebXR): each eye sees its endoscope camera on a screen fixed in the
// room, like the da Vinci's viewer (turning the head does not carry the image along), and
// the XR controllers are the MTMs through the page's hand-input path: the controller's
// motion becomes the rate input the keys and gamepads send (scaled, capped by the server's
// hand speed), its trigger the gripper, A/X the clutch, B/Y the camera pedal; the guidance
// force comes back as haptic pulses. The session being shown is the head sensor.
//
// The mapping functions are pure (tested in the browser); XrConsole is the session.

import { GRIPPER_CLOSED, GRIPPER_OPEN, rumbleIntensity } from "./input.js";

// Controller to hand motion: 1 m of the controller moves the master's handle this much.
export const XR_MOTION_SCALE = 0.5;
// A controller's rate input goes out at most this often, ms (its mean over the interval).
export const SEND_EVERY_MS = 20;
// The fixed screen: this far in front of where the head was when the session began, m,
// and this high (its width follows the image's aspect).
export const SCREEN_DISTANCE_M = 1.0;
export const SCREEN_HEIGHT_M = 0.8;
// xr-standard gamepad buttons (WebXR Gamepads Module): 0 trigger, 4 A/X, 5 B/Y.
const TRIGGER = 0, BUTTON_A = 4, BUTTON_B = 5;

const clamp1 = (v) => Math.max(-1, Math.min(1, v));

// The rate input of a controller that moved from `prev` to `pose` (each { position: [x, y,
// z] m, orientation: [x, y, z, w] }, in the session's "local" space: x right, y up, -z
// ahead) in `dtS` s. Screen axes as the page sends them: [right, up, in] and the turn
// about them, each in [-1, 1] of the server's handSpeed (m/s) and turnSpeed (rad/s).
export function xrRate(prev, pose, dtS, { scale = XR_MOTION_SCALE, handSpeed, turnSpeed }) {
  if (!prev || !(dtS > 0)) return { axes: [0, 0, 0], turn: [0, 0, 0] };
  const d = pose.position.map((v, i) => (scale * (v - prev.position[i])) / dtS);
  const axes = [d[0], d[1], -d[2]].map((v) => clamp1(v / handSpeed));
  // The rotation from prev to pose, in the local space: q = pose * conj(prev).
  const [ax, ay, az, aw] = pose.orientation, [bx, by, bz, bw] = prev.orientation;
  const cx = -bx, cy = -by, cz = -bz;
  let qx = aw * cx + ax * bw + ay * cz - az * cy;
  let qy = aw * cy - ax * cz + ay * bw + az * cx;
  let qz = aw * cz + ax * cy - ay * cx + az * bw;
  let qw = aw * bw - ax * cx - ay * cy - az * cz;
  if (qw < 0) { qx = -qx; qy = -qy; qz = -qz; qw = -qw; }  // (the short way round)
  const s = Math.hypot(qx, qy, qz);
  const angle = 2 * Math.atan2(s, qw);
  const w = s > 1e-12 ? [qx, qy, qz].map((v) => (v / s) * (angle / dtS)) : [0, 0, 0];
  const turn = [w[0], w[1], -w[2]].map((v) => clamp1(v / turnSpeed));
  return { axes, turn };
}

// A controller's buttons (xr-standard mapping): the trigger closes the gripper (rad),
// A/X is the clutch, B/Y the camera pedal.
export function xrButtons(gamepad) {
  const b = gamepad?.buttons || [];
  const value = (i) => (b[i] ? Number(b[i].value) || (b[i].pressed ? 1 : 0) : 0);
  const pressed = (i) => !!b[i] && (b[i].pressed || b[i].value > 0.5);
  const t = Math.max(0, Math.min(1, value(TRIGGER)));
  return {
    gripper: GRIPPER_OPEN - t * (GRIPPER_OPEN - GRIPPER_CLOSED),
    clutch: pressed(BUTTON_A),
    camera: pressed(BUTTON_B),
  };
}

// The MTM a controller drives: the right hand's the right master.
export function mtmOfHand(handedness) {
  return handedness === "left" ? "MTML" : handedness === "right" ? "MTMR" : null;
}

// A haptic pulse for the guidance force (N) of the largest forceMax: [intensity, ms] or null.
export function hapticPulse(force, forceMax, durationMs = 30) {
  const intensity = rumbleIntensity(force, forceMax);
  return intensity > 0.02 ? [intensity, durationMs] : null;
}

function poseOf(xrPose) {
  const p = xrPose.transform.position, o = xrPose.transform.orientation;
  return { position: [p.x, p.y, p.z], orientation: [o.x, o.y, o.z, o.w] };
}

// The immersive session: `view` is the page's EndoscopeView; `io` the page's side:
// input(mtm, axes, turn, gripper), button(name, pressed), force(mtm) -> N, forceMax,
// handSpeed, turnSpeed, onEnd(), and overlay: the heads-up display's canvas (or null).
export class XrConsole {
  constructor(view, io) {
    this.view = view; this.io = io;
    this.session = null; this.frames = 0;
    this.last = new Map();  // input source -> { pose, t } when its input last went out
    this.buttons = { clutch: false, camera: false };
  }

  static async supported() {
    try {
      return !!navigator.xr && (await navigator.xr.isSessionSupported("immersive-vr"));
    } catch (e) {
      return false;
    }
  }

  async start() {
    const THREE = this.view.THREE, renderer = this.view.renderer;
    const session = await navigator.xr.requestSession("immersive-vr", { requiredFeatures: ["local"] });
    const gl = renderer.getContext();
    if (gl.makeXRCompatible) {  // (a browser without an XR device may never answer)
      const late = new Promise((_, reject) =>
        setTimeout(() => reject(new Error("the WebGL context did not become XR-compatible")), 10000));
      try {
        await Promise.race([gl.makeXRCompatible(), late]);
      } catch (e) {
        await session.end();
        throw e;
      }
    }
    this.layer = new XRWebGLLayer(session, gl);
    session.updateRenderState({ baseLayer: this.layer });
    this.space = await session.requestReferenceSpace("local");
    this.session = session;
    const { width: w, height: h } = this.view;
    this.targets = [0, 1].map(() => new THREE.WebGLRenderTarget(w, h));
    // The heads-up display (the page's overlay canvas: text, tool marks, guidance arrow)
    // on both screens, just in front of the image; its marks are the left image's pixels,
    // so in the right eye they sit a disparity's few pixels off the tool.
    this.hud = this.io.overlay ? new THREE.CanvasTexture(this.io.overlay) : null;
    this.eyes = this.targets.map((t) => {
      const scene = new THREE.Scene();
      const height = SCREEN_HEIGHT_M, width = (height * w) / h;
      const screen = new THREE.Mesh(new THREE.PlaneGeometry(width, height),
        new THREE.MeshBasicMaterial({ map: t.texture }));
      screen.position.set(0, 0, -SCREEN_DISTANCE_M);
      scene.add(screen);
      if (this.hud) {
        const hud = new THREE.Mesh(new THREE.PlaneGeometry(width, height),
          new THREE.MeshBasicMaterial({ map: this.hud, transparent: true, depthTest: false }));
        hud.position.set(0, 0, -SCREEN_DISTANCE_M + 0.001);
        scene.add(hud);
      }
      return scene;
    });
    this.camera = new THREE.PerspectiveCamera();  // (each XR view's matrices as given)
    this.camera.matrixAutoUpdate = false;
    this.camera.matrixWorldAutoUpdate = false;
    this.output = null;
    session.addEventListener("end", () => this.ended());
    session.addEventListener("visibilitychange", () =>
      this.io.button("operator_present", session.visibilityState === "visible"));
    this.io.button("operator_present", true);  // the head is in the viewer
    session.requestAnimationFrame((t, frame) => this.onFrame(t, frame));
    return this;
  }

  onFrame(t, frame) {
    const session = this.session;
    if (!session) return;
    session.requestAnimationFrame((t2, f2) => this.onFrame(t2, f2));
    this.readControllers(t, frame);
    const viewer = frame.getViewerPose(this.space);
    if (!viewer) return;
    const { THREE, renderer } = this.view;
    for (const eye of [0, 1]) {  // each endoscope camera into its texture
      renderer.setRenderTarget(this.targets[eye]);
      renderer.setViewport(0, 0, this.view.width, this.view.height);
      this.view.renderEye(eye);
    }
    if (this.hud) this.hud.needsUpdate = true;
    const layer = this.layer;
    if (layer.framebuffer) {
      if (!this.output) {
        this.output = new THREE.WebGLRenderTarget(layer.framebufferWidth, layer.framebufferHeight);
        renderer.setRenderTargetFramebuffer(this.output, layer.framebuffer);
      }
      renderer.setRenderTarget(this.output);
    } else {
      renderer.setRenderTarget(null);
    }
    renderer.clear();
    for (const v of viewer.views) {
      const vp = layer.getViewport(v);
      renderer.setViewport(vp.x, vp.y, vp.width, vp.height);
      this.camera.projectionMatrix.fromArray(v.projectionMatrix);
      this.camera.projectionMatrixInverse.copy(this.camera.projectionMatrix).invert();
      this.camera.matrixWorld.fromArray(v.transform.matrix);
      this.camera.matrixWorldInverse.copy(this.camera.matrixWorld).invert();
      renderer.render(this.eyes[v.eye === "right" ? 1 : 0], this.camera);
    }
    renderer.setRenderTarget(null);
    this.frames += 1;
  }

  readControllers(t, frame) {
    const io = this.io;
    const buttons = { clutch: false, camera: false };
    for (const source of this.session.inputSources || []) {
      const mtm = mtmOfHand(source.handedness);
      if (!mtm || !source.gripSpace) continue;
      const xrPose = frame.getPose(source.gripSpace, this.space);
      if (!xrPose) continue;
      const pose = poseOf(xrPose);
      const last = this.last.get(source);
      const b = xrButtons(source.gamepad);
      buttons.clutch ||= b.clutch; buttons.camera ||= b.camera;
      if (!last) {
        this.last.set(source, { pose, t });
      } else if (t - last.t >= SEND_EVERY_MS) {
        const rate = xrRate(last.pose, pose, (t - last.t) / 1000,
          { handSpeed: io.handSpeed, turnSpeed: io.turnSpeed });
        io.input(mtm, rate.axes, rate.turn, b.gripper);
        this.last.set(source, { pose, t });
      }
      const pulse = hapticPulse(io.force(mtm), io.forceMax);
      const actuator = source.gamepad?.hapticActuators?.[0];
      if (pulse && actuator?.pulse) actuator.pulse(...pulse);
    }
    for (const name of ["clutch", "camera"]) {
      if (buttons[name] !== this.buttons[name]) io.button(name, buttons[name]);
    }
    this.buttons = buttons;
  }

  async stop() {
    if (this.session) await this.session.end();
  }

  ended() {
    if (!this.session) return;
    this.session = null;
    for (const t of this.targets || []) t.dispose();
    if (this.hud) this.hud.dispose();
    if (this.output) this.output.dispose();
    this.io.button("operator_present", false);
    for (const mtm of new Set([...this.last.keys()].map((s) => mtmOfHand(s.handedness)))) {
      if (mtm) this.io.input(mtm, [0, 0, 0], [0, 0, 0], null);
    }
    this.last.clear();
    this.io.onEnd();
  }
}
