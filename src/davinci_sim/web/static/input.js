// The operator's input in the page: keyboard and gamepad (a SpaceMouse that the browser
// shows as a gamepad counts as one) turned into the console's commands.
//
// Pure functions of the input state, so they are testable without a simulation:
//   keyAxes(pressed)        -> [right, up, in] in [-1, 1] from the keys held down
//   keyTurn(pressed)        -> the wrist's rate about [right, up, in] in [-1, 1]
//   gamepadInput(gamepad)   -> {axes, gripper, buttons} from one Gamepad API object
// The server turns the axes into the hand's velocity (HRSV, m/s): the tool moves the same
// way in the endoscope image (right, up, into the scene), scaled by the teleoperation.

export const GRIPPER_OPEN = (60 * Math.PI) / 180; // rad, the MTM gripper's range (dvrk.md 1.5)
// "Closed" squeezes the gripper past just closed (0) to -15°: the teleoperation makes that a
// -20° jaw goal (jaw = 80°/60° x gripper, dvrk.md 4.2), the dVRK's close, so the jaws grip
// what they hold with their full effort (a goal of 0 stops pressing once nearly closed).
export const GRIPPER_CLOSED = (-15 * Math.PI) / 180;
// The jaw key's "open": the gripper at 45°, the jaw at 60°, the dVRK's jaw.open() (dvrk.md
// 3.2). Wide open (80°), the jaws reach over a ring's peg when they go down on its wall.
export const GRIPPER_KEY_OPEN = (45 * Math.PI) / 180;

// The key map shown in the page. `axis`: [index, sign] of the hand's rate; `turn`: [index,
// sign] of the wrist's rate about the screen's right, up and in axes (right-hand rule);
// `button`: a console button held while the key is down; `toggle`: an action on key down.
export const KEYMAP = [
  { keys: ["KeyD", "ArrowRight"], label: "D / →", what: "tool right", axis: [0, +1] },
  { keys: ["KeyA", "ArrowLeft"], label: "A / ←", what: "tool left", axis: [0, -1] },
  { keys: ["KeyW", "ArrowUp"], label: "W / ↑", what: "tool up", axis: [1, +1] },
  { keys: ["KeyS", "ArrowDown"], label: "S / ↓", what: "tool down", axis: [1, -1] },
  { keys: ["KeyR", "PageUp"], label: "R / PgUp", what: "tool deeper (into the scene)", axis: [2, +1] },
  { keys: ["KeyF", "PageDown"], label: "F / PgDn", what: "tool back (out of the scene)", axis: [2, -1] },
  { keys: ["KeyI"], label: "I", what: "turn the tool: tip up", turn: [0, +1] },
  { keys: ["KeyK"], label: "K", what: "turn the tool: tip down", turn: [0, -1] },
  { keys: ["KeyJ"], label: "J", what: "turn the tool: tip left", turn: [1, +1] },
  { keys: ["KeyL"], label: "L", what: "turn the tool: tip right", turn: [1, -1] },
  { keys: ["KeyO"], label: "O", what: "roll the tool clockwise", turn: [2, +1] },
  { keys: ["KeyU"], label: "U", what: "roll the tool counter-clockwise", turn: [2, -1] },
  { keys: ["Space"], label: "Space (hold)", what: "clutch pedal", button: "clutch" },
  { keys: ["KeyC"], label: "C (hold)", what: "camera pedal: the keys move both hands, which steer the endoscope (the image follows the hands)", button: "camera" },
  { keys: ["KeyE"], label: "E", what: "open / close the jaw", toggle: "jaw" },
  { keys: ["KeyH"], label: "H", what: "switch hand: right (MTMR → PSM1) / left (MTML → PSM2)", toggle: "hand" },
  { keys: ["KeyP"], label: "P", what: "head sensor: operator present on / off", toggle: "present" },
  { keys: ["ShiftLeft", "ShiftRight"], label: "Shift (hold)", what: "fine motion (¼ speed)", toggle: "fine" },
];

const AXIS_KEYS = new Map();
const TURN_KEYS = new Map();
const BUTTON_KEYS = new Map();
const TOGGLE_KEYS = new Map();
for (const entry of KEYMAP) {
  for (const k of entry.keys) {
    if (entry.axis) AXIS_KEYS.set(k, entry.axis);
    if (entry.turn) TURN_KEYS.set(k, entry.turn);
    if (entry.button) BUTTON_KEYS.set(k, entry.button);
    if (entry.toggle) TOGGLE_KEYS.set(k, entry.toggle);
  }
}

export function isMappedKey(code) {
  return AXIS_KEYS.has(code) || TURN_KEYS.has(code) || BUTTON_KEYS.has(code) || TOGGLE_KEYS.has(code);
}

export function buttonOfKey(code) {
  return BUTTON_KEYS.get(code) ?? null;
}

export function toggleOfKey(code) {
  return TOGGLE_KEYS.get(code) ?? null;
}

// Axes from the set of key codes held down: opposite keys cancel; Shift gives 1/4.
export function keyAxes(pressed) {
  const axes = [0, 0, 0];
  for (const code of pressed) {
    const a = AXIS_KEYS.get(code);
    if (a) axes[a[0]] += a[1];
  }
  const fine = pressed.has("ShiftLeft") || pressed.has("ShiftRight") ? 0.25 : 1;
  return axes.map((v) => Math.max(-1, Math.min(1, v)) * fine);
}

// The wrist's rate from the keys held down: opposite keys cancel; Shift gives 1/4.
export function keyTurn(pressed) {
  const turn = [0, 0, 0];
  for (const code of pressed) {
    const a = TURN_KEYS.get(code);
    if (a) turn[a[0]] += a[1];
  }
  const fine = pressed.has("ShiftLeft") || pressed.has("ShiftRight") ? 0.25 : 1;
  return turn.map((v) => Math.max(-1, Math.min(1, v)) * fine);
}

// Dead zone of the sticks: below it an axis reads 0 (sticks do not rest exactly at 0).
export const DEAD_ZONE = 0.12;

function dead(v) {
  if (!Number.isFinite(v) || Math.abs(v) < DEAD_ZONE) return 0;
  const s = (Math.abs(v) - DEAD_ZONE) / (1 - DEAD_ZONE);
  return Math.sign(v) * Math.min(1, s);
}

function pressed(gamepad, i) {
  const b = gamepad.buttons?.[i];
  return !!b && (b.pressed || b.value > 0.5);
}

function value(gamepad, i) {
  const b = gamepad.buttons?.[i];
  return b ? Number(b.value) || (b.pressed ? 1 : 0) : 0;
}

export function isSpaceMouse(gamepad) {
  return /3dconnexion|spacemouse|space navigator|spacenavigator/i.test(gamepad.id || "");
}

// One gamepad's input, W3C "standard" mapping: left stick = right/up, right stick vertical
// = in/out (push forward: deeper), right trigger closes the jaw; A (0) clutch, B (1) camera
// pedal. A SpaceMouse as a gamepad: its axes 0, 1, 2 are x (right), y (towards the user),
// z (down): right, in, -up here; its two buttons clutch and jaw.
export function gamepadInput(gamepad) {
  const ax = gamepad.axes || [];
  if (isSpaceMouse(gamepad)) {
    return {
      axes: [dead(ax[0] ?? 0), -dead(ax[2] ?? 0), -dead(ax[1] ?? 0)],
      gripper: pressed(gamepad, 1) ? GRIPPER_CLOSED : GRIPPER_OPEN,
      buttons: { clutch: pressed(gamepad, 0), camera: false },
    };
  }
  return {
    axes: [dead(ax[0] ?? 0), -dead(ax[1] ?? 0), -dead(ax[3] ?? 0)],
    gripper: GRIPPER_OPEN - Math.max(0, Math.min(1, value(gamepad, 7))) * (GRIPPER_OPEN - GRIPPER_CLOSED),
    buttons: { clutch: pressed(gamepad, 0), camera: pressed(gamepad, 1) },
  };
}

// Rumble of a gamepad for a force of `force` N when the largest is `forceMax` N: the
// intensity in [0, 1] the haptic actuator gets (0: none).
export function rumbleIntensity(force, forceMax) {
  if (!(forceMax > 0) || !Number.isFinite(force)) return 0;
  return Math.max(0, Math.min(1, Math.abs(force) / forceMax));
}

export function rumble(gamepad, intensity, durationMs = 120) {
  const actuator = gamepad?.vibrationActuator;
  if (!actuator || !(intensity > 0.02)) return false;
  if (typeof actuator.playEffect === "function") {
    actuator
      .playEffect("dual-rumble", {
        duration: durationMs,
        strongMagnitude: intensity,
        weakMagnitude: intensity,
      })
      .catch(() => {});
    return true;
  }
  return false;
}

export function sameAxes(a, b) {
  return !!a && !!b && a.every((v, i) => Math.abs(v - b[i]) < 1e-3);
}
