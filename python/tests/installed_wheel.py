"""What a user with only the wheel gets: run by scripts/test-python with the
Python of a fresh virtual environment into which pip installed the built
wheel, with no Rust toolchain on PATH.

    python installed_wheel.py WHEEL

Checks that nothing of the source tree or of Rust is in reach, that the wheel
is the abi3 manylinux wheel pip installed (its tag, its one extension
module), then imports the package, scans the simulated bus and an in-process
emulator over loopback UDP, and writes and reads back a register through the
emulator. (Not a pytest file: pytest runs the suite itself against the same
installed package afterwards.)
"""

from __future__ import annotations

import os
import re
import shutil
import sys
import sysconfig
from importlib import metadata
from pathlib import Path

def check(condition: bool, what: str) -> None:
    if not condition:
        sys.exit(f"installed wheel: {what}")


def glibc() -> tuple[int, int]:
    version = os.confstr("CS_GNU_LIBC_VERSION") or ""  # "glibc 2.36"
    m = re.fullmatch(r"glibc (\d+)\.(\d+)", version)
    check(m is not None, f"not a glibc system ({version!r}): the manylinux check needs one")
    return int(m.group(1)), int(m.group(2))


def main() -> None:
    check(len(sys.argv) == 2, "usage: installed_wheel.py WHEEL")
    wheel = Path(sys.argv[1])
    for tool in ("cargo", "rustc", "rustup", "maturin"):
        found = shutil.which(tool)
        check(found is None, f"{tool} is on PATH ({found}); the check needs a PATH without Rust")

    # The wheel's file name and the tag pip recorded: one abi3 wheel for
    # every CPython >= 3.9, manylinux at or below this machine's glibc.
    tag = re.fullmatch(r"firelink-[^-]+-(cp39-abi3-manylinux_(\d+)_(\d+)_x86_64)\.whl", wheel.name)
    check(tag is not None, f"{wheel.name} is not a cp39-abi3-manylinux_X_Y_x86_64 wheel")
    major, minor = int(tag.group(2)), int(tag.group(3))
    check((major, minor) <= glibc(), f"{wheel.name} needs glibc {major}.{minor}, this machine has {glibc()}")
    dist = metadata.distribution("firelink")
    lines = (dist.read_text("WHEEL") or "").splitlines()
    recorded = [line.split(":", 1)[1].strip() for line in lines if line.startswith("Tag:")]
    check(recorded == [tag.group(1)], f"pip installed a wheel tagged {recorded}, not {tag.group(1)}")

    import firelink

    site = Path(sysconfig.get_paths()["purelib"]).resolve()
    package = Path(firelink.__file__).resolve().parent
    check(package == site / "firelink", f"firelink was imported from {package}, not from {site}")
    modules = sorted(p.name for p in package.iterdir() if p.suffix == ".so")
    check(modules == ["_firelink.abi3.so"], f"the package holds {modules}, not one abi3 module")
    files = [str(f) for f in dist.files or []]
    for name in ("_firelink.abi3.so", "__init__.py", "_errors.py", "_firelink.pyi", "py.typed"):
        check(f"firelink/{name}" in files, f"firelink/{name} is missing from the wheel")

    # The simulated bus: seed 000's eight QLA boards.
    boards = firelink.open("sim").scan()
    ids = [b.board_id for b in boards]
    check(ids == list(range(8)), f"a scan of sim found boards {ids}")

    # The in-process emulator over loopback UDP, all sixteen board IDs
    # taken so that the scan waits for no absent node; 2 s per answer (the
    # emulator runs in this process: a late answer is a stalled thread).
    with firelink.Emulator(boards=16, firmware="7") as emu:
        check(emu.address.startswith("udp:127.0.0.1:"), f"the emulator listens on {emu.address}")
        port = emu.port(timeout=2.0)
        found = [(b.board_id, b.firmware) for b in port.scan()]
        check(found == [(i, 7) for i in range(16)], f"a scan of the emulator found {found}")
        io = firelink.IoSystem(port)
        io.write_register(2, 3, 500)  # board 2's watchdog period, in ticks
        back = io.read_register(2, 3) & 0xFFFF
        check(back == 500, f"board 2's watchdog register written 500 read back {back}")
    check(not emu.running, "the emulator still runs after its with block")
    print(f"installed wheel: {wheel.name} works from {package} without Rust")


if __name__ == "__main__":
    main()
