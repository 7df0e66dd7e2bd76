"""Marks for the tests of a guarantee only a POSIX path gives (m3c2kit.base.portable): skipped when
the capability is missing, as under ``M3C2_PORTABLE_FALLBACKS=1``, which runs the fallbacks on
Linux. Each reason names what the fallback lacks; docs/architecture.md, "Portability", lists them."""
from __future__ import annotations

import pytest

from m3c2kit.base import portable


def _has(capability: str) -> bool:
    if capability == "kernel_locks":  # lockf, or msvcrt's byte locks
        return portable.kernel_locks()
    return getattr(portable.CAPS, capability)


def needs(*capabilities: str, why: str):
    """Skip unless every one of `capabilities` (fields of portable.Capabilities, or kernel_locks)
    is in use."""
    missing = [c for c in capabilities if not _has(c)]
    return pytest.mark.skipif(bool(missing), reason=f"without {', '.join(missing)}: {why} "
                                                    f"(docs/architecture.md, 'Portability')")
