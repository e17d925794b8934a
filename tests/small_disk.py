"""A command on a small disk of its own: run inside ``unshare --user --map-root-user --mount`` (no
root needed where user namespaces are on), it mounts a tmpfs of the given size on FOLDER (seen by
this process and its children only, gone with them), runs the command there and reports as JSON
what happened and what the folder then holds (tests/test_environment_faults.py).

    unshare -rm python tests/small_disk.py FOLDER SIZE_KB [--fill-when-running KEEP_KB | --read-only-when-running]
                                           -- COMMAND...

--fill-when-running: once the command's stderr says its run is running (the line a run prints
when its clock starts), fill the disk to leave KEEP_KB free: its files then do not fit when it
writes them, though they fitted when it checked. --read-only-when-running: then remount the disk
read-only instead.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import time
from pathlib import Path


def main() -> int:
    args = sys.argv[1:]
    split = args.index("--")
    options, command = args[:split], args[split + 1:]
    folder, size_kb = Path(options[0]), int(options[1])
    keep_kb = int(options[options.index("--fill-when-running") + 1]) if "--fill-when-running" in options else None
    read_only = "--read-only-when-running" in options
    folder.mkdir(parents=True, exist_ok=True)
    subprocess.run(["mount", "-t", "tmpfs", "-o", f"size={size_kb}k", "tmpfs", str(folder)], check=True)
    err_path = Path(os.environ.get("TMPDIR", "/tmp")) / f"small-disk-{os.getpid()}.err"
    with open(err_path, "w+") as err:
        proc = subprocess.Popen(command, stdout=subprocess.PIPE, stderr=err, text=True)
        filled = False
        while (keep_kb is not None or read_only) and not filled and proc.poll() is None:
            err.seek(0)
            if ": running (" in err.read():
                if read_only:
                    subprocess.run(["mount", "-o", "remount,ro", str(folder)], check=True)
                else:
                    free = os.statvfs(folder).f_bavail * os.statvfs(folder).f_frsize
                    with open(folder / ".filler", "wb") as filler:
                        filler.write(b"\0" * max(0, free - keep_kb * 1024))
                filled = True
            time.sleep(0.02)
        out, _ = proc.communicate(timeout=600)
        err.seek(0)
        stderr = err.read()
    err_path.unlink()
    if not read_only:
        (folder / ".filler").unlink(missing_ok=True)
    files = sorted(str(p.relative_to(folder)) for p in folder.rglob("*"))
    kept = {str(p.relative_to(folder)): p.read_text() for p in folder.rglob("metrics.json")}
    print(json.dumps({"code": proc.returncode, "stdout": out, "stderr": stderr, "files": files, "filled": filled,
                      "metrics": kept}))
    return 0


if __name__ == "__main__":
    sys.exit(main())
