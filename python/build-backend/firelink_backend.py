"""The package's PEP 517 build backend: maturin's, with a manylinux tag.

maturin's own backend gives every PEP 517 wheel (``pip wheel``, ``pip
install``, ``python -m build``) the plain ``linux_x86_64`` tag: it passes
``--compatibility off`` unless the build's arguments name a compatibility,
and that flag wins over a ``compatibility`` in ``[tool.maturin]``. Such a
wheel installs only where it was built. This backend passes
``--compatibility`` with no value instead, maturin's default for ``maturin
build``: it audits the extension's symbols and libraries and tags the wheel
with the lowest manylinux (or musllinux) policy they satisfy, e.g.
``cp39-abi3-manylinux_2_34_x86_64``; the plain tag only where none fits. A
compatibility the caller names (``MATURIN_PEP517_ARGS`` or ``-C
build-args=...``) is used as given. Every other hook is maturin's.
"""

from __future__ import annotations

from typing import Any, Mapping, Optional

import maturin
from maturin import (  # noqa: F401  (the hooks this backend does not change)
    build_editable,
    build_sdist,
    get_requires_for_build_editable,
    get_requires_for_build_sdist,
    get_requires_for_build_wheel,
    prepare_metadata_for_build_editable,
    prepare_metadata_for_build_wheel,
)


_FLAGS = ("--compatibility", "--manylinux")


def _split_flags(args: list[str]) -> list[str]:
    """``--compatibility=X`` as two words, the only form maturin's own
    backend recognises (with ``=`` it adds ``off`` as well and fails)."""
    out = []
    for a in args:
        flag, eq, value = a.partition("=")
        out.extend([flag, value] if eq and flag in _FLAGS else [a])
    return out


def build_wheel(
    wheel_directory: str,
    config_settings: Optional[Mapping[str, Any]] = None,
    metadata_directory: Optional[str] = None,
) -> str:
    args = _split_flags(list(maturin.get_maturin_pep517_args(config_settings)))
    if not any(flag in args for flag in _FLAGS):
        args.append("--compatibility")  # no value: the lowest policy that fits
    settings = {k: v for k, v in (config_settings or {}).items() if k != "maturin.build-args"}
    settings["build-args"] = args
    return maturin.build_wheel(wheel_directory, settings, metadata_directory)
