// Reads the viewer page's readouts once a second through the DevTools protocol of a
// headless chromium started with --remote-debugging-port=PORT (see docs/viewer.md).
const port = process.argv[2];
const sleep = (ms) => new Promise((r) => setTimeout(r, ms));
let list;
for (let i = 0; i < 50; i++) {
  try { list = await (await fetch(`http://127.0.0.1:${port}/json/list`)).json(); if (list.length) break; } catch (e) {}
  await sleep(200);
}
const page = list.find((t) => t.type === "page");
const ws = new WebSocket(page.webSocketDebuggerUrl);
await new Promise((r) => (ws.onopen = r));
let id = 0; const pending = new Map();
ws.onmessage = (ev) => { const m = JSON.parse(ev.data); if (pending.has(m.id)) { pending.get(m.id)(m); pending.delete(m.id); } };
const call = (method, params) => new Promise((r) => { const i = ++id; pending.set(i, r); ws.send(JSON.stringify({ id: i, method, params })); });
const ev = async (expr) => (await call("Runtime.evaluate", { expression: expr, returnByValue: true })).result.result.value;
for (let k = 0; k < 12; k++) {
  await sleep(1000);
  console.log(await ev(`[document.getElementById('force').textContent, document.getElementById('timing').textContent, document.getElementById('frameinfo').textContent, document.getElementById('status').textContent].join(' | ')`));
}
process.exit(0);
