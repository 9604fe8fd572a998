"""A moreau-server process on 127.0.0.1 for tests written in Python: started on a free port (the
server picks it and prints it), with its own data directory, and stopped (SIGTERM, then waited for) when
the `with` block ends, whatever happened in it."""

import os
import re
import signal
import subprocess
import tempfile
import threading


class ServerProcess:
    def __init__(self, binary, scenes_dir, extra_args=()):
        self.binary = binary
        self.scenes_dir = scenes_dir
        self.extra_args = list(extra_args)
        self.url = None
        self._proc = None
        self._tmp = None
        self.log = []

    def __enter__(self):
        self._tmp = tempfile.TemporaryDirectory(prefix="moreau-test-")
        cmd = [self.binary, "--host", "127.0.0.1", "--port", "0", "--workers", "2",
               "--data", os.path.join(self._tmp.name, "data"), "--scenes", self.scenes_dir] + self.extra_args
        self._proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
        # The server prints its address once it listens: wait for that line (the state the tests need),
        # not for a fixed time. A server that exits first ends the wait with its output.
        for line in self._proc.stdout:
            self.log.append(line)
            m = re.search(r"listening on (http://127\.0\.0\.1:\d+)", line)
            if m:
                self.url = m.group(1)
                break
        if self.url is None:
            self._proc.wait()
            raise RuntimeError("moreau-server did not start: " + "".join(self.log))
        # Keep draining its output so that it never blocks on a full pipe.
        threading.Thread(target=lambda: self.log.extend(self._proc.stdout), daemon=True).start()
        return self

    def __exit__(self, *exc):
        if self._proc.poll() is None:
            self._proc.send_signal(signal.SIGTERM)
            try:
                self._proc.wait(timeout=30)
            except subprocess.TimeoutExpired:
                self._proc.kill()
                self._proc.wait()
        self._tmp.cleanup()
        return False
