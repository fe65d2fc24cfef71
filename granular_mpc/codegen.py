"""Compile CasADi functions to a shared library once, cached on disk by source hash.

    fns = compile_functions("plant", [step, step.mapaccum(10)])   # name -> callable Function

The C source CasADi generates for the functions is hashed (with the CasADi version and the
compiler flags); the library ``<cache>/<prefix>_<hash>.so`` is built with the system C
compiler when missing and loaded with ``casadi.external``. The hash covers everything the
code depends on — the robot model, the terrain law and its effects, the step settings —
so a changed model gets a new library and an unchanged one is never rebuilt.

Cache folder: ``$GRANULAR_MPC_CACHE`` or ``~/.cache/granular_mpc`` (the same folder as the
terrain's compiled contact law: :mod:`granular_mpc.terrain.contact` builds it here
too). ``GRANULAR_MPC_JIT=0`` with ``fallback=True``: CasADi's virtual machine. Compiler: ``$CC``, else ``cc`` or ``gcc`` on the PATH;
flags ``-O3 -fPIC -shared`` (``-fopenmp`` for code with OpenMP maps). Without a compiler,
:func:`compile_functions` raises :class:`~granular_mpc.exceptions.ModelError` unless
``fallback=True``, which returns the functions for CasADi's virtual machine (slow).

Building prints one line on stderr (``compiling <prefix> … (once; cached in <folder>)``).
Processes that need the same library at once (sweep workers, parallel test runs) are
safe: the build holds an exclusive lock on ``<library>.lock`` (``fcntl``), so one
process compiles and the others wait and load its result; the library appears
atomically (``os.replace``), so no process ever loads half a file.
"""

from __future__ import annotations

import hashlib
import os
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path
from typing import Sequence

import casadi as ca

from .exceptions import ModelError
from .output import exclusive_lock

#: optimisation flags (no -ffast-math: it would change fmin/fmax/NaN semantics)
CFLAGS = ("-O3", "-fPIC", "-shared")


def cache_dir() -> Path:
    """Folder of compiled libraries: ``$GRANULAR_MPC_CACHE`` or ``~/.cache/granular_mpc``."""
    return Path(os.environ.get("GRANULAR_MPC_CACHE", Path.home() / ".cache" / "granular_mpc"))


def compiler() -> str | None:
    """The C compiler to use (``$CC`` if it exists, else ``cc`` or ``gcc``), or None."""
    cc = os.environ.get("CC")
    if cc:
        return shutil.which(cc)
    return shutil.which("cc") or shutil.which("gcc")


def compile_functions(prefix: str, functions: Sequence[ca.Function], *,
                      fallback: bool = False, optimisation: str = "-O3") -> dict[str, ca.Function]:
    """Generate C for ``functions``, build (or reuse) the cached library, load each function.

    Args:
        prefix: file-name prefix of the library.
        functions: CasADi functions with distinct names.
        fallback: without a compiler (or if ``GRANULAR_MPC_JIT=0``, or the build fails),
            return the functions themselves instead of raising.
        optimisation: the compiler's optimisation flag (part of the cache key).

    Returns:
        Function name → ``casadi.external`` function from the library.
    """
    cc = compiler()
    if fallback and os.environ.get("GRANULAR_MPC_JIT", "1") == "0":
        return {f.name(): f for f in functions}
    if cc is None:
        if fallback:
            return {f.name(): f for f in functions}
        raise ModelError("no C compiler found (set CC) to build the compiled plant")
    cache = cache_dir()
    try:
        cache.mkdir(parents=True, exist_ok=True)
    except OSError:                         # read-only home: a per-user temporary folder
        cache = Path(tempfile.gettempdir()) / f"granular_mpc-cache-{os.getuid()}"
        try:
            cache.mkdir(parents=True, exist_ok=True)
        except OSError as exc:
            if fallback:
                return {f.name(): f for f in functions}
            raise ModelError(f"no writable cache folder for compiled code: {exc}") from exc
    with tempfile.TemporaryDirectory() as tmp:
        cg = ca.CodeGenerator("gen.c", {"with_header": False})
        for f in functions:
            cg.add(f)
        cg.generate(tmp + os.sep)
        src_path = Path(tmp, "gen.c")
        src = src_path.read_bytes()
        flags = ([optimisation] + [f for f in CFLAGS if not f.startswith("-O")]
                 + (["-fopenmp"] if b"#pragma omp" in src else []))
        key = hashlib.sha256(src + ca.__version__.encode() + " ".join(flags).encode())
        lib = cache / f"{prefix}_{key.hexdigest()[:20]}.so"
        if not lib.is_file():
            with exclusive_lock(lib.with_suffix(".lock")):    # one build; the others wait
                if not lib.is_file():       # another process may have built it meanwhile
                    try:
                        _build(cc, flags, src_path, lib, prefix)
                    except (OSError, subprocess.SubprocessError) as exc:
                        if fallback:
                            return {f.name(): f for f in functions}
                        detail = getattr(exc, "stderr", b"") or b""
                        raise ModelError(f"compiling the plant failed: {exc} "
                                         f"{detail.decode(errors='replace')[:400]}") from exc
    return {f.name(): ca.external(f.name(), str(lib)) for f in functions}


def _build(cc: str, flags: list[str], src_path: Path, lib: Path, prefix: str) -> None:
    """Compile ``src_path`` to ``lib`` (atomically), announcing it in one stderr line."""
    size_kb = src_path.stat().st_size / 1024
    print(f"granular_mpc: compiling {prefix} ({size_kb:.0f} kB of C, once; cached in "
          f"{lib.parent}) …", file=sys.stderr, flush=True)
    out = src_path.with_suffix(".so")
    subprocess.run([cc, *flags, str(src_path), "-o", str(out), "-lm"], check=True,
                   capture_output=True, timeout=1800)
    partial = lib.with_suffix(f".{os.getpid()}.tmp")
    shutil.copyfile(out, partial)
    os.replace(partial, lib)                # atomic: parallel builds never see half a file


__all__ = ["CFLAGS", "cache_dir", "compiler", "compile_functions"]
