"""The campaign's partial-result store: finished batches survive a crash and a rerun resumes from them.

Layout of the output directory::

    manifest.json          the campaign's settings and their fingerprint
    batches/<key>.npz      one file per finished batch (written to a temporary name, then renamed: a killed
                           process leaves either the whole file or none)

A rerun with the same settings (same fingerprint) reuses every readable batch file and computes only the
rest — the results are deterministic, so this is exact. A directory holding a campaign with *different*
settings is refused (nothing is overwritten) unless ``fresh=True`` discards its batches.
"""

from __future__ import annotations

import json
import os
import zipfile
from pathlib import Path
from typing import Any

import numpy as np

from board_config.errors import InputError
from studies.campaign.spec import CampaignSpec
from studies.campaign.worker import BatchResult


class CampaignStoreError(InputError):
    """The output directory holds a different campaign (or an unreadable manifest)."""


class ResultStore:
    """Finished batches of one campaign in ``out_dir`` (see the module doc)."""

    def __init__(self, out_dir: str | Path, spec: CampaignSpec, fresh: bool = False) -> None:
        self.out_dir = Path(out_dir)
        self.spec = spec
        self.fingerprint = spec.fingerprint()
        self.batch_dir = self.out_dir / "batches"
        self.manifest_path = self.out_dir / "manifest.json"
        self.notes: list[str] = []
        self.out_dir.mkdir(parents=True, exist_ok=True)
        if self.manifest_path.exists():
            try:
                old = json.loads(self.manifest_path.read_text())
                old_fp = old["fingerprint"]
            except (OSError, ValueError, KeyError, TypeError) as exc:
                if not fresh:
                    raise CampaignStoreError(f"{self.manifest_path}: unreadable campaign manifest ({exc}); pass "
                                             f"--fresh to discard the stored batches, or use another --out") from None
                old, old_fp = {}, None
            if old_fp != self.fingerprint:
                if not fresh:
                    diff = _differences(old.get("spec", {}), spec.describe())
                    raise CampaignStoreError(
                        f"{self.out_dir} holds batches of a different campaign ({diff}); rerun with the same "
                        f"settings to resume it, choose another --out, or pass --fresh to discard them")
                self._discard()
            elif fresh:
                self._discard()
        self.batch_dir.mkdir(exist_ok=True)
        tmp = self.manifest_path.with_name(".manifest.json.tmp")
        tmp.write_text(json.dumps({"fingerprint": self.fingerprint, "spec": spec.describe()}, indent=2))
        tmp.replace(self.manifest_path)

    def _discard(self) -> None:
        if self.batch_dir.exists():
            for f in self.batch_dir.glob("*.npz"):
                f.unlink()
        self.notes.append(f"discarded the stored batches in {self.batch_dir} (--fresh)")

    def path(self, key: str) -> Path:
        return self.batch_dir / f"{key}.npz"

    def save(self, result: BatchResult) -> Path:
        """Store a finished batch atomically."""
        path = self.path(result.key)
        tmp = self.batch_dir / f".{result.key}.{os.getpid()}.tmp"
        with tmp.open("wb") as fh:
            np.savez(fh, allow_pickle=False, _fingerprint=np.array(self.fingerprint),  # loaded without pickles too
                     _elapsed_s=np.array(result.elapsed_s), _worker=np.array(result.worker), **result.arrays)
        tmp.replace(path)
        return path

    def load(self, key: str) -> dict[str, np.ndarray] | None:
        """A stored batch's arrays, or ``None`` if absent or unreadable (then it is recomputed, with a note)."""
        path = self.path(key)
        if not path.exists():
            return None
        try:
            with np.load(path, allow_pickle=False) as z:
                if str(z["_fingerprint"]) != self.fingerprint:
                    raise ValueError("belongs to another campaign")
                return {k: z[k] for k in z.files if not k.startswith("_")}
        except (OSError, ValueError, KeyError, zipfile.BadZipFile, EOFError) as exc:
            self.notes.append(f"{path}: unreadable ({exc}); recomputing that batch")
            return None

    def finished(self) -> dict[str, dict[str, np.ndarray]]:
        """Every readable stored batch of this campaign, by key."""
        out = {}
        for batch in self.spec.batches():
            arrays = self.load(batch.key)
            if arrays is not None:
                out[batch.key] = arrays
        return out


def _differences(old: dict[str, Any], new: dict[str, Any]) -> str:
    """The keys two campaign specs differ in (both as the store's manifest.json holds them: JSON documents)."""
    keys = sorted(k for k in set(old) | set(new) if old.get(k) != new.get(k))
    if not keys:
        return "different fingerprint"
    parts = []
    for k in keys[:4]:
        a, b = old.get(k), new.get(k)
        if isinstance(a, (dict, list)) or isinstance(b, (dict, list)):
            parts.append(f"{k} differs")
        else:
            parts.append(f"{k}: stored {a!r}, requested {b!r}")
    return "; ".join(parts)
