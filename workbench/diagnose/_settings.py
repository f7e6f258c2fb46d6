"""How :func:`workbench.diagnose.diagnose` runs: one frozen settings object instead of fourteen keywords."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, fields, replace
from pathlib import Path
from typing import TYPE_CHECKING, Any

from workbench.fit import DEFAULT_BLOCKS, DEFAULT_MAX_RATE_HZ, MIN_REDUCTION

if TYPE_CHECKING:
    from workbench.diagnose._progress import DiagnoseProgress
    from workbench.fit import CandidateResult

#: candidates of each kind fitted in full after screening (None: all)
FIT_TOP = 3


@dataclass(frozen=True)
class DiagnoseSettings:
    """Settings of one diagnosis (defaults: the command's)."""

    #: how the records are split into training and held-out parts ("blocks", ...)
    holdout: str = "blocks"
    #: number of interleaved blocks of the "blocks" hold-out (count)
    n_blocks: int = DEFAULT_BLOCKS
    #: highest sample rate the records are decimated to before fitting (Hz)
    max_rate_Hz: float = DEFAULT_MAX_RATE_HZ
    #: least share of the held-out residual energy a candidate must remove to be accepted (fraction, 0–1)
    min_reduction: float = MIN_REDUCTION
    #: candidates fitted concurrently in threads (count; 1: serial)
    workers: int = 1
    #: most residual evaluations per least-squares fit (count)
    max_nfev: int = 30
    #: seed of the multi-start and screening draws (integer)
    seed: int = 0
    #: called when a candidate starts (result None) and when it is done
    progress: Callable[[str, CandidateResult | None], None] | None = None
    #: integrate the Jacobian's columns in one batch (False: one at a time, the benchmark's baseline)
    batched_jacobian: bool = True
    #: after screening, fit in full only the best this many of each kind (count; None: all)
    fit_top: int | None = FIT_TOP
    #: run forward selection when the winner leaves more than the forward threshold
    combine: bool = True
    #: how the fit command names the parameter set (default: its name)
    params_label: str | None = None
    #: hears each stage start and each unit of work done
    reporter: DiagnoseProgress | None = None
    #: directory for the discovery step's effect file (None: no discovery)
    emit_dir: str | Path | None = None
    #: hears the discovery step's progress
    on_discover: Callable[[str], None] | None = None

    def with_options(self, options: dict[str, Any]) -> DiagnoseSettings:
        """These settings with ``options`` (field names) replaced; an unknown name is a TypeError,
        as an unknown keyword argument was."""
        known = {f.name for f in fields(self)}
        unknown = sorted(set(options) - known)
        if unknown:
            raise TypeError(f"diagnose() got unexpected keyword argument(s) {', '.join(unknown)}")
        return replace(self, **options) if options else self
