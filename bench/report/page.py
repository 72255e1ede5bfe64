"""What every section builder shares: the staged report directory, plots, thumbnails and links.

The report is staged as a whole (``index.html`` and ``plots/``) and renamed into place. Every
image the page shows is embedded in it as a data URI, so ``index.html`` alone is the report (it
shows everything when copied alone): plots (also kept as PNG files in ``plots/``, for reuse) and
thumbnails of the samples' images. Links to sample and reconstruction folders (and to the
full-size images) are relative to the report's final place, so they work where the report sits
beside its data. What cannot be shown faithfully (an image that is missing, truncated, differs
from its recorded checksum, or is a link) is left out and said (``Page.leave_out``: the page's
notes and the ``warn`` callback).

Sections hand the templates plain dicts. A *generic section* (what
``bench.report.sensing.study_section`` / ``sensing_section`` return, and the interim adapters
in ``bench.report.interim``) is::

    {"title": str,
     "summary": str,                                      optional, one paragraph
     "outcome": str,                                      optional: a sensing run's outcome class
     "figures": [{"label", "value", "unit", "status"[, "warning"]}],   key figures; or {label: value};
                                                          "warning": a line shown beside the figure
     "tables":  [{"title", "caption", "rows": [dict, ...], "columns": [key or {"key", "label"}]}],
     "plots":   [{"file", "caption"[, "left_out"]}],      PNG names in the out_dir handed to the builder;
                                                          "left_out": lines saying what a plot left out
                                                          (file None: the whole plot, and why)
     "links":   [{"label", "path"}],                      optional: folders or files, relative to the
                                                          input folder handed to the builder
     "notes":   [str]}

``normalise_section`` accepts that form and a few obvious variants (``key_figures`` for
``figures``, a table given as a bare list of dicts, ``(file, caption)`` pairs), and turns it into
what ``templates/section.html`` renders.
"""
from __future__ import annotations

import base64
import os
from dataclasses import dataclass, field
from pathlib import Path

from platebench.bench.config.axes import PARAMETER_NAMES, parameter_label
from platebench.bench.io.atomic import target_of_temp
from platebench.bench.io.images import DatasetError
from platebench.bench.io.layout import SAMPLE, SAMPLES
from platebench.bench.io.verify import dataset_manifest, find_links, sample_checksums, verify_sample
from platebench.bench.report.plots import drawn
from platebench.bench.report.thumbs import sample_thumbnails
from platebench.bench.report.values import flag
from platebench.evaluation.metrics_row import is_metric, metric_label
from platebench.scenes.naming import IMAGE_NAMES

__all__ = ["Page", "normalise_section", "table_of", "column_label"]


@dataclass
class Page:
    """The report being written: ``stage`` is the staged directory that becomes ``out``; ``root`` the
    input folder; ``colours`` the one {method: colour} map every plot of the report takes
    (``bench.report.colours.method_colours``; empty: each plot colours its own methods in sorted
    order). Paths are shown as the reader finds them: relative to ``root`` or to the report's folder,
    staging names replaced by the outputs they become (``bench.io.atomic.target_of_temp``)."""

    stage: Path
    out: Path
    root: Path
    notes: list = field(default_factory=list)
    warn: object = None  # callable(message): told of each part left out (also a note)
    colours: dict = field(default_factory=dict)
    _manifests: dict = field(default_factory=dict)

    def leave_out(self, message: str) -> None:
        """Say that a part is not shown, and why: a note on the page (its paths as ``shown`` gives them)
        and a warning (as given)."""
        note = self.shown(message)
        if note not in self.notes:
            self.notes.append(note)
            if self.warn is not None:
                self.warn(message)

    def shown(self, text: str) -> str:
        """``text`` with the input folder's absolute path written as its name (the reader's view)."""
        root = str(self.root.resolve())
        return str(text).replace(root + os.sep, self.root_name + "/").replace(root, self.root_name)

    @property
    def root_name(self) -> str:
        """The input folder's name, as it is once its output is in place (never a staging name)."""
        return target_of_temp(self.root.resolve()).name or str(self.root)

    def checksums(self, sample_dir: Path):
        """The recorded checksums of a sample's files (``bench.io.verify``), the dataset manifest read once."""
        d = Path(sample_dir)
        manifest = {}
        if d.name == SAMPLE and d.parent.parent.name == SAMPLES:
            ds = d.parent.parent.parent.resolve()
            if ds not in self._manifests:
                self._manifests[ds] = dataset_manifest(ds) or {}
            manifest = self._manifests[ds]
        return sample_checksums(d, manifest)

    @property
    def plot_dir(self) -> Path:
        (self.stage / "plots").mkdir(exist_ok=True)
        return self.stage / "plots"

    def section_dir(self, anchor: str) -> Path:
        """A folder of its own under ``plots/`` for a section builder that writes its own PNGs."""
        (self.plot_dir / anchor).mkdir(exist_ok=True)
        return self.plot_dir / anchor

    def figure(self, path: Path, caption: str, alt: str = "") -> dict:
        """A PNG already in ``plots/`` as a template figure (embedded as a data URI)."""
        data = base64.b64encode(Path(path).read_bytes()).decode("ascii")
        return {"src": f"data:image/png;base64,{data}", "caption": caption, "alt": alt or Path(path).stem,
                "file": Path(path).resolve().relative_to(self.stage.resolve()).as_posix()}

    def plot(self, name: str, fn, *args, caption: str, **kwargs) -> dict:
        """Draw ``fn(*args, plots/<name>.png, **kwargs)`` and return it as a template figure, the report's
        ``colours`` handed to a plot that takes them. A figure with nothing to show is not kept: the
        returned figure then has ``src`` None and ``left_out`` one line saying why (``plots.drawn``);
        panels a plot left out are said in ``left_out`` too."""
        import inspect  # noqa: PLC0415
        if self.colours and "colours" in inspect.signature(fn).parameters:
            kwargs.setdefault("colours", self.colours)
        path, left = drawn(fn, *args, self.plot_dir / f"{name}.png", **kwargs)
        if path is None:
            what = kwargs.get("title") or name
            return {"src": None, "caption": caption, "alt": name, "file": None,
                    "left_out": [f"plot '{what}' left out: {left.figure}"]}
        return {**self.figure(path, caption, alt=name), "left_out": list(left.panels)}

    def link(self, path: Path) -> str:
        """``path`` relative to the report's final folder (POSIX separators; a folder ends in /)."""
        rel = Path(os.path.relpath(Path(path).resolve(), self.out.resolve())).as_posix()
        return rel + "/" if Path(path).is_dir() else rel

    def rel(self, path: Path) -> str:
        """``path`` as the reader knows it: relative to the input directory where it lies inside (the
        input directory itself: its name), else relative to the report's folder."""
        try:
            r = Path(path).resolve().relative_to(self.root.resolve())
            return str(r) if str(r) != "." else self.root_name
        except ValueError:
            return self.from_report(path)

    def from_report(self, path: Path) -> str:
        """``path`` relative to the report's final folder (POSIX separators), staging names replaced."""
        out = target_of_temp(self.out.resolve())
        return Path(os.path.relpath(target_of_temp(Path(path).resolve()), out)).as_posix()

    def sample_problem(self, folder: Path) -> str | None:
        """Why a dataset sample's files may not be read for the page (a link inside its folder, a file
        that differs from its recorded checksum), or None."""
        links = find_links(folder)
        if links:
            return f"{links[0]} is a symbolic link (to {os.readlink(links[0])}): not followed"
        sample = Path(folder) / SAMPLE
        try:
            verify_sample(sample, self.checksums(sample), then="")
        except DatasetError as e:
            return str(e)
        return None

    def thumbnails(self, sample_dir: Path, names=IMAGE_NAMES) -> list[dict]:
        """Thumbnails of a sample's camera images (default all four), embedded: [{"name", "src" (a PNG
        data URI) and "href" (the full image, relative); both None when the image is not shown, which
        ``leave_out`` says}]."""
        sample_dir = Path(sample_dir)
        try:  # the folders from the input down to the sample (a link above the input is the user's own)
            inside = [self.root.joinpath(*sample_dir.relative_to(self.root).parts[:k + 1])
                      for k in range(len(sample_dir.relative_to(self.root).parts))]
        except ValueError:
            inside = [sample_dir]
        link = next((p for p in inside if p.is_symlink()), None)
        if link is not None:
            self.leave_out(f"{sample_dir}: {link} is a symbolic link: its images are not shown (a link can lead "
                           "out of the input)")
            return [{"name": n, "src": None, "href": None} for n in names]
        checks = self.checksums(sample_dir)

        def check(image: Path) -> None:
            verify_sample(sample_dir, checks, [image.relative_to(sample_dir).as_posix()], then="")
        out = []
        for t in sample_thumbnails(sample_dir, names, check=check):
            if t["problem"]:
                self.leave_out(f"{t['problem']}: its thumbnail is not shown")
            shown = t["png"] is not None
            out.append({"name": t["name"],
                        "src": "data:image/png;base64," + base64.b64encode(t["png"]).decode() if shown else None,
                        "href": self.link(sample_dir / "images" / f"{t['name']}.png") if shown else None})
        return out


# ----------------------------------------------------------------------------- generic sections
def column_label(key: str) -> str:
    """A column's label with its unit: a parameter's (``parameter_label``), a metric's (``metric_label``:
    a shared field or an extra column's family), else the name with spaces."""
    if key in PARAMETER_NAMES:
        return parameter_label(key)
    if is_metric(key):
        return metric_label(key)
    return str(key).replace("_", " ")


def table_of(rows: list[dict], columns=None, title: str = "", caption: str = "") -> dict:
    """A template table from a list of row dicts: {"title", "caption", "columns": [{"key", "label"}],
    "rows": [[value, ...]]}; columns default to every key in first-seen order."""
    if columns is None:
        columns = list(dict.fromkeys(k for r in rows for k in r))
    cols = [c if isinstance(c, dict) else {"key": c, "label": column_label(c)} for c in columns]
    return {"title": title, "caption": caption, "columns": cols,
            "rows": [[r.get(c["key"]) for c in cols] for r in rows]}


def _figures(figs) -> list[dict]:
    if isinstance(figs, dict):
        figs = [{"label": k, "value": v} for k, v in figs.items()]
    out = []
    for f in figs or []:
        if isinstance(f, (tuple, list)):
            f = dict(zip(("label", "value", "unit"), f))
        status = f.get("status")
        if status is None and flag(f.get("value")) is not None:
            status = "good" if f["value"] else "bad"
        out.append({"label": str(f.get("label", "")), "value": f.get("value"), "unit": f.get("unit") or "",
                    "status": status or "", "warning": str(f.get("warning") or "")})
    return out


def _tables(tables) -> list[dict]:
    if isinstance(tables, dict):
        tables = [{"title": k, "rows": v} for k, v in tables.items()]
    out = []
    for t in tables or []:
        if isinstance(t, list):
            t = {"rows": t}
        rows = [r for r in t.get("rows") or [] if isinstance(r, dict)]
        out.append(table_of(rows, t.get("columns"), str(t.get("title") or ""), str(t.get("caption") or "")))
    return out


def _plots(page: Page, plots, out_dir: Path) -> list[dict]:
    if isinstance(plots, dict):
        plots = list(plots.items())
    out = []
    for p in plots or []:
        name, caption = (p if isinstance(p, (tuple, list)) else
                         (p.get("file") or p.get("name") or p.get("path"), p.get("caption", "")))
        left = [str(n) for n in (p.get("left_out") or [])] if isinstance(p, dict) else []
        path = Path(out_dir) / Path(str(name)).name
        if name is None and left:  # a plot with nothing to show: the line saying so
            out.append({"src": None, "caption": str(caption or ""), "alt": "", "file": None, "left_out": left})
        elif path.is_file():
            out.append({**page.figure(path, str(caption or "")), "left_out": left})
        else:
            page.notes.append(f"plot {name} named by a section was not written")
    return out


def _links(page: Page, links, base: Path) -> list[dict]:
    out = []
    for link in links or []:
        label, path = (link if isinstance(link, (tuple, list)) else (link.get("label"), link.get("path")))
        target = Path(base) / str(path)
        if target.exists():
            out.append({"label": str(label or path), "href": page.link(target)})
    return out


def normalise_section(page: Page, d: dict, out_dir: Path, base: Path) -> dict:
    """A generic section dict (module doc) as ``templates/section_generic.html`` renders it; ``base``
    is the input folder the section was made from (its links are relative to it)."""
    return {"title": str(d.get("title") or ""), "summary": d.get("summary") or "",
            "outcome": d.get("outcome"),
            "figures": _figures(d.get("figures", d.get("key_figures"))),
            "tables": _tables(d.get("tables")), "plots": _plots(page, d.get("plots"), out_dir),
            "links": _links(page, d.get("links"), base), "notes": [str(n) for n in d.get("notes") or []]}
