// A dVRK socket-streamer client in plain Node.js (no packages): JSON over UDP, both ways.
//
//   davinci-sim serve --udp            # streams PSM1 to 127.0.0.1:48051
//   node examples/udp_psm.js [port]    # this script, listening on that port
//
// The simulator sends one datagram per value, e.g. {"measured_js": {"Name": [...],
// "Position": [...], ...}}, and the arm's events ({"operating_state": {...}},
// {"error": "PSM1: ..."}). Commands go back to the address the datagrams come from, one JSON
// object per datagram: {"state_command": "enable"}, {"move_jp": {"Goal": [...]}}.
"use strict";
const dgram = require("dgram");

const port = Number(process.argv[2] || 48051);
const goal = [0.1, -0.05, 0.12, 0.0, 0.0, 0.0]; // rad, rad, m, rad, rad, rad
const sock = dgram.createSocket("udp4");
let sim = null; // the simulator's command address, learnt from its first datagram
let step = "enable";

function send(obj) {
  sock.send(JSON.stringify(obj), sim.port, sim.address);
}

function done(code, text) {
  console.log(text);
  sock.close();
  process.exit(code);
}

sock.on("message", (data, from) => {
  const msg = JSON.parse(data.toString());
  if (sim === null) {
    sim = from;
    send({ state_command: "enable" });
    send({ state_command: "home" });
  }
  const state = msg.operating_state;
  if (step === "enable" && state && state.IsHomed && !state.IsBusy) {
    console.log("homed");
    step = "move";
    send({ move_jp: { Goal: goal } });
  }
  const js = msg.measured_js;
  if (step === "move" && js && js.Position.every((q, i) => Math.abs(q - goal[i]) < 2e-3)) {
    console.log("move_jp reached " + JSON.stringify(js.Position.map((q) => +q.toFixed(3))));
    step = "bad";
    // far beyond the insertion limit: refused (a goal nearer a limit is clipped to it)
    send({ move_jp: { Goal: [0, 0, 5000.0, 0, 0, 0] } });
  }
  if (step === "bad" && msg.error) {
    done(0, "refused: " + msg.error);
  }
});

setTimeout(() => done(1, "timed out at step " + step), 60000);
sock.bind(port, "127.0.0.1");
