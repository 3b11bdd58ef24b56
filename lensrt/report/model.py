"""The report as data: sections of blocks (text, tables, figures, files), Monte Carlo records,
and the context the sections share (lens, options, output folder, cached comparison)."""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from ..io.table import Table
from .options import ReportOptions

__all__ = ["Figure", "MonteCarlo", "Report", "ReportContext", "Section"]


@dataclass
class Figure:
    """An image file in the report folder, shown with a caption (``file`` relative to the folder)."""

    file: str
    caption: str
    wide: bool = False


@dataclass
class MonteCarlo:
    """How one Monte Carlo figure or table was made: its samples, run time and standard error.

    ``stderr`` is a sentence (e.g. "largest 0.0009 (0.4 %) over 11 fields") because a figure
    holds many estimates; ``stderr_max`` the largest standard error as a number, in ``unit``.
    """

    figure: str
    quantity: str
    samples: int
    seconds: float
    stderr: str
    method: str = ""
    stderr_max: float | None = None
    unit: str = ""

    def to_dict(self) -> dict[str, Any]:
        return {"figure": self.figure, "quantity": self.quantity, "samples": int(self.samples),
                "seconds": float(self.seconds), "stderr": self.stderr, "stderr_max": self.stderr_max,
                "unit": self.unit, "method": self.method}


@dataclass
class Section:
    """One section of the page. Blocks are ``(kind, payload)``: ``text`` (str), ``table``
    (:class:`Table`), ``figure`` (:class:`Figure`), ``files`` (list of (file, what)), ``pre`` (str),
    ``details`` ((summary, list of blocks)): collapsed on the page."""

    key: str
    title: str
    blocks: list[tuple[str, Any]] = field(default_factory=list)
    errors: list[str] = field(default_factory=list)
    warnings: list[str] = field(default_factory=list)
    monte_carlo: list[MonteCarlo] = field(default_factory=list)
    data: dict[str, Any] = field(default_factory=dict)
    seconds: float = 0.0
    traceback: str = ""
    #: kernel launches, host<->device copies, wall and kernel seconds (lensrt.core.telemetry)
    telemetry: dict[str, Any] = field(default_factory=dict)

    @property
    def ok(self) -> bool:
        return not self.errors

    def text(self, s: str) -> None:
        self.blocks.append(("text", s))

    def table(self, t: Table) -> None:
        self.blocks.append(("table", t))

    def figure(self, file: str | Path, caption: str, wide: bool = False) -> None:
        self.blocks.append(("figure", Figure(Path(file).name, caption, wide)))

    def files(self, files: list[tuple[str, str]]) -> None:
        self.blocks.append(("files", [(Path(f).name, what) for f, what in files]))

    def details(self, summary: str, blocks: list[tuple[str, Any]]) -> None:
        self.blocks.append(("details", (summary, blocks)))

    def mc(self, record: MonteCarlo) -> None:
        self.monte_carlo.append(record)

    def referenced_files(self) -> list[str]:
        """Every file a block of this section points at."""
        out = []

        def walk(blocks):
            for kind, payload in blocks:
                if kind == "figure":
                    out.append(payload.file)
                elif kind == "files":
                    out.extend(f for f, _ in payload)
                elif kind == "details":
                    walk(payload[1])
        walk(self.blocks)
        return out

    def to_dict(self) -> dict[str, Any]:
        return {"key": self.key, "title": self.title, "ok": self.ok, "errors": self.errors, "warnings": self.warnings,
                "seconds": self.seconds, **self.telemetry, "files": self.referenced_files(),
                "monte_carlo": [m.to_dict() for m in self.monte_carlo], "data": self.data,
                **({"traceback": self.traceback} if self.traceback else {})}


@dataclass
class ReportContext:
    """What the sections share: the lens as analysed, the file's lens, options, folder, device."""

    lens: Any
    file_lens: Any
    options: Any
    out_dir: Path
    device: str
    lens_notes: list[str] = field(default_factory=list)
    progress: Any = None
    cache: dict[str, Any] = field(default_factory=dict)
    _comparison: Any = None
    _comparison_error: BaseException | None = None

    @property
    def infinite(self) -> bool:
        return math.isinf(self.lens.object_distance_mm)

    def comparison(self):
        """:func:`lensrt.analysis.compare.comparison.compare_lens` of the lens, computed once (its error re-raised)."""
        if self._comparison is None and self._comparison_error is None:
            from ..analysis.compare.comparison import compare_lens
            q = self.options.preset
            try:
                self._comparison = compare_lens(self.lens, device=self.device, rays=q.compare_rays,
                                                spot_rays=q.spot_rays, seed=self.options.seed)
            except Exception as err:  # noqa: BLE001 - raised here, and named by every later section
                self._comparison_error = err
                raise
        if self._comparison_error is not None:
            from ..errors import LensrtError
            raise LensrtError(f"needs the paraxial-against-real comparison, which failed: {self._comparison_error}")
        return self._comparison

    def path(self, name: str) -> Path:
        return self.out_dir / name


@dataclass
class Report:
    """A finished report: its sections, where its files are, and how it was made."""

    lens_name: str
    options: ReportOptions
    sections: list[Section]
    out_dir: Path
    device: str
    device_name: str
    seconds: float
    environment: dict[str, Any]
    lens_notes: list[str] = field(default_factory=list)
    summary: dict[str, Any] = field(default_factory=dict)
    key_numbers: list[dict[str, Any]] = field(default_factory=list)
    #: the whole report's {wall_s, kernel_s, launches, copies} (lensrt.core.telemetry)
    telemetry: dict[str, Any] = field(default_factory=dict)
    #: the Warp modules the report planned and loaded up front (lensrt.report.kernel_plan)
    kernel_modules: list[dict[str, Any]] = field(default_factory=list)
    html_path: Path | None = None
    json_path: Path | None = None

    @property
    def failed(self) -> list[Section]:
        return [s for s in self.sections if not s.ok]

    @property
    def monte_carlo(self) -> list[dict]:
        return [dict(section=s.title, **m.to_dict()) for s in self.sections for m in s.monte_carlo]

    def referenced_files(self) -> list[str]:
        out = [f for s in self.sections for f in s.referenced_files()]
        return list(dict.fromkeys(out))

    def to_dict(self) -> dict[str, Any]:
        return {"lens": self.lens_name, "summary": self.summary, "key_numbers": self.key_numbers,
                "options": self.options.to_dict(),
                "lens_changes": self.lens_notes, "device": self.device, "device_name": self.device_name,
                "seconds": self.seconds, "telemetry": self.telemetry, "environment": self.environment,
                "ok": not self.failed, "failed_sections": [s.key for s in self.failed],
                "monte_carlo": self.monte_carlo, "files": self.referenced_files() + ["index.html"],
                "sections": [s.to_dict() for s in self.sections]}
