// What the browser tests share: a check that prints what it held, and a moreau-server on 127.0.0.1 with a
// token, started on a free port it picks and stopped with SIGTERM.
import { spawn } from 'node:child_process';
import fs from 'node:fs';
import path from 'node:path';
import readline from 'node:readline';

export function check(condition, message) {
  if (!condition) throw new Error('check failed: ' + message);
  console.log('ok:', message);
}

// The server prints the port it picked: wait for that line, not for a time.
export async function startServer(serverBin, sourceDir, dataDir, token) {
  const proc = spawn(serverBin, ['--host', '127.0.0.1', '--port', '0', '--token', token, '--workers', '2',
                                 '--data', dataDir, '--scenes', path.join(sourceDir, 'scenes')],
                     { stdio: ['ignore', 'pipe', 'inherit'] });
  const lines = readline.createInterface({ input: proc.stdout });
  const url = await new Promise((resolve, reject) => {
    lines.on('line', (line) => {
      const m = line.match(/listening on (http:\/\/127\.0\.0\.1:\d+)/);
      if (m) resolve(m[1]);
    });
    proc.on('exit', (code) => reject(new Error('moreau-server exited with ' + code + ' before listening')));
  });
  lines.on('line', () => {});  // keep draining
  return { proc, url };
}

export async function stopServer(proc) {
  if (proc.exitCode !== null) return;
  const exited = new Promise((resolve) => proc.on('exit', resolve));
  proc.kill('SIGTERM');
  await exited;
}

// Runs a test's main(): "browser test passed", or its error and exit status 1.
export function run(main) {
  main().then(() => console.log('browser test passed'), (e) => {
    console.error(e.stack || String(e));
    process.exit(1);
  });
}

// After a test, whatever happened: the browser closed, the server stopped, its data removed.
export async function cleanUp(browser, proc, dataDir) {
  if (browser) await browser.close();
  await stopServer(proc);
  fs.rmSync(dataDir, { recursive: true, force: true });
}
