"""The lens report as one self-contained HTML page: inline CSS, no network resources, relative
links to the figures and data files beside it.

The page carries a tiny inline script that, once everything has loaded, marks each ``<img>``
whose ``naturalWidth`` is 0 with ``data-broken`` and sets ``data-images`` on ``<body>`` to
``ok`` or ``broken`` (and ``data-broken-images`` to the count): a headless browser's
``--dump-dom`` shows whether the page renders whole (tests/test_report.py).
"""
from __future__ import annotations

import html
import math
import re
from pathlib import Path
from typing import Any

from ..io.table import Table, format_cell

from .model import Report

__all__ = ["write_html", "render_html", "html_table", "pretty"]

_CSS = """
:root { --ink: #1d2733; --muted: #5b6776; --line: #d8dee6; --bg: #f6f8fa; --accent: #1b5e9f;
        --bad: #b42318; --badbg: #fdecea; --ok: #1e7b34; --okbg: #e8f5ec; }
* { box-sizing: border-box; }
body { margin: 0; font: 15px/1.5 system-ui, -apple-system, "Segoe UI", Roboto, "Helvetica Neue", Arial, sans-serif;
       color: var(--ink); background: #fff; }
header { background: var(--bg); border-bottom: 1px solid var(--line); }
.wrap { max-width: 1240px; margin: 0 auto; padding: 0 24px; }
header .wrap { padding-top: 20px; padding-bottom: 16px; }
h1 { font-size: 28px; margin: 0 0 2px; }
h1 small { font-size: 15px; color: var(--muted); font-weight: normal; margin-left: 8px; }
h2 { font-size: 21px; margin: 36px 0 8px; padding-top: 8px; border-top: 2px solid var(--line); }
h2 .n { color: var(--muted); margin-right: 6px; }
p { margin: 6px 0; max-width: 1100px; }
.sub { color: var(--muted); font-size: 16px; margin-bottom: 12px; }
.status { padding: 8px 12px; border-radius: 6px; margin: 10px 0; font-weight: 600; }
.status.ok { background: var(--okbg); color: var(--ok); }
.status.bad, .error { background: var(--badbg); color: var(--bad); }
.error { padding: 8px 12px; border-radius: 6px; margin: 8px 0; border: 1px solid #f5c2bd; }
.top { display: grid; grid-template-columns: minmax(0, 1.5fr) minmax(0, 1fr); gap: 24px; align-items: start; }
@media (max-width: 900px) { .top { grid-template-columns: 1fr; } }
.tables { display: flex; flex-wrap: wrap; gap: 4px 32px; align-items: flex-start; margin: 10px 0; }
.tblock { flex: 0 1 auto; max-width: 100%; }
p.tt { font-weight: 600; font-size: 13.5px; margin: 8px 0 2px; max-width: 560px; }
table { border-collapse: collapse; font-size: 13px; margin: 2px 0 12px; }
th, td { padding: 3px 9px; border-bottom: 1px solid var(--line); white-space: nowrap; }
th { background: var(--bg); text-align: right; font-weight: 600; }
td { text-align: right; font-variant-numeric: tabular-nums; }
td.t, th.t { text-align: left; }
tbody tr:nth-child(even) td { background: #fbfcfd; }
table.kv td, table.kv th { text-align: left; white-space: normal; vertical-align: top; }
table.kv th { width: 150px; background: none; color: var(--muted); font-weight: 500; }
.tw { overflow-x: auto; max-width: 100%; }
nav ol { margin: 4px 0; padding-left: 22px; columns: 2; font-size: 14px; }
nav a { color: var(--accent); text-decoration: none; }
nav .mark { font-size: 12px; margin-left: 6px; }
.mark.ok { color: var(--ok); } .mark.bad { color: var(--bad); } .mark.skip { color: var(--muted); }
.figs { display: grid; grid-template-columns: repeat(auto-fill, minmax(520px, 1fr)); gap: 18px; margin: 10px 0; }
figure { margin: 0; border: 1px solid var(--line); border-radius: 6px; padding: 8px; background: #fff; }
figure.wide { grid-column: 1 / -1; }
figure img { display: block; max-width: 100%; height: auto; margin: 0 auto; }
figure.wide img { max-height: 760px; }
figcaption { font-size: 13px; color: var(--muted); margin-top: 6px; }
img[data-broken] { outline: 3px solid var(--bad); min-height: 40px; min-width: 80px; }
p.warn { color: #8a5a00; background: #fff6e0; padding: 4px 10px; border-radius: 4px; font-size: 14px; }
details { margin: 8px 0; }
summary { cursor: pointer; color: var(--accent); font-size: 14px; }
ul.files { font-size: 14px; margin: 6px 0; }
code, .cmd { font-family: ui-monospace, SFMono-Regular, Menlo, Consolas, monospace; font-size: 13px; }
.cmd { background: var(--bg); border: 1px solid var(--line); padding: 6px 10px; border-radius: 4px;
       white-space: pre-wrap; word-break: break-all; }
pre { background: var(--bg); padding: 8px; overflow-x: auto; font-size: 12px; }
.keys { display: flex; flex-wrap: wrap; gap: 10px; margin: 12px 0 16px; }
a.key { display: flex; flex-direction: column; background: #fff; border: 1px solid var(--line); border-radius: 6px;
        padding: 6px 12px; min-width: 128px; text-decoration: none; color: var(--ink); }
a.key:hover { border-color: var(--accent); }
.kl { font-size: 12px; color: var(--muted); text-transform: uppercase; letter-spacing: 0.03em; }
.kval { font-size: 19px; font-weight: 600; font-variant-numeric: tabular-nums; }
.kn { font-size: 12px; color: var(--muted); }
footer { color: var(--muted); font-size: 13px; padding: 24px 0 40px; }
"""

_SCRIPT = """
(function () {
  function check() {
    var imgs = document.images, broken = 0, pending = 0;
    for (var i = 0; i < imgs.length; i++) {
      var im = imgs[i];
      if (!im.complete) { pending++; continue; }
      if (im.naturalWidth === 0) { im.setAttribute('data-broken', '1'); broken++; }
    }
    document.body.setAttribute('data-images', pending ? 'loading' : (broken ? 'broken' : 'ok'));
    document.body.setAttribute('data-broken-images', String(broken));
  }
  window.addEventListener('load', check);
})();
"""


def pretty(text: str) -> str:
    """Plain-ASCII notation as people read it: +- as a plus-minus sign, um as micrometres, squares."""
    text = text.replace("+-", "\u00b1")
    text = re.sub(r"\bum\b", "\u00b5m", text)
    return text.replace("cos^4", "cos\u2074").replace("mm^2", "mm\u00b2").replace("mm2", "mm\u00b2")


def _e(text: Any) -> str:
    return html.escape(pretty(str(text)), quote=True)


def _numeric(text: str) -> bool:
    return bool(re.fullmatch(r"[-+]?(inf|nan|[0-9.]+(e[-+]?[0-9]+)?)|-|[-+0-9.e ,\u00b1]+", text))


def html_table(t: Table, cls: str = "") -> str:
    """A :class:`Table` as HTML: its title above it, numbers right-aligned with the table's decimals
    (a column is right-aligned when every cell in it reads as a number)."""
    cells = [[format_cell(v, t.digits) for v in row] for row in t.rows]
    ncol = len(t.headers)
    right = [j > 0 and all(_numeric(pretty(r[j])) for r in cells if j < len(r)) for j in range(ncol)]
    head = "".join(f'<th class="{"" if right[j] else "t"}">{_e(h)}</th>' for j, h in enumerate(t.headers))
    body = "".join("<tr>" + "".join(f'<td class="{"" if j < ncol and right[j] else "t"}">{_e(c)}</td>'
                                    for j, c in enumerate(r)) + "</tr>" for r in cells)
    cap = f'<p class="tt">{_e(t.title)}</p>' if t.title else ""
    return (f'<div class="tblock">{cap}<div class="tw"><table class="{cls}"><thead><tr>{head}</tr></thead>'
            f"<tbody>{body}</tbody></table></div></div>")


def _figure(fig) -> str:
    src = html.escape(fig.file, quote=True)
    return (f'<figure class="{"wide" if fig.wide else ""}"><a href="{src}"><img src="{src}" alt="{_e(fig.file)}">'
            f"</a><figcaption><code>{_e(fig.file)}</code> \u2014 {_e(fig.caption)}</figcaption></figure>")


def _blocks(blocks: list) -> str:
    """HTML of a section's blocks: runs of figures share a grid, runs of tables flow side by side."""
    out: list[str] = []
    run: list[str] = []
    run_kind = ""

    def flush() -> None:
        if run:
            out.append(f'<div class="{"figs" if run_kind == "figure" else "tables"}">' + "".join(run) + "</div>")
            run.clear()
    for kind, payload in blocks:
        if kind in ("figure", "table"):
            if kind != run_kind:
                flush()
                run_kind = kind
            run.append(_figure(payload) if kind == "figure" else html_table(payload))
            continue
        flush()
        run_kind = ""
        if kind == "text":
            out.append(f"<p>{_e(payload)}</p>")
        elif kind == "files":
            items = "".join(f'<li><a href="{html.escape(f, quote=True)}"><code>{_e(f)}</code></a> \u2014 {_e(w)}</li>'
                            for f, w in payload)
            out.append(f'<ul class="files">{items}</ul>')
        elif kind == "pre":
            out.append(f"<pre>{html.escape(str(payload))}</pre>")
        elif kind == "details":
            summary, inner = payload
            out.append(f"<details><summary>{_e(summary)}</summary>{_blocks(inner)}</details>")
    flush()
    return "".join(out)


def _kv(rows: list[tuple[str, str]], raw: frozenset[str] = frozenset()) -> str:
    cells = "".join(f"<tr><th>{_e(k)}</th><td>{v if k in raw else _e(v)}</td></tr>" for k, v in rows)
    return f'<table class="kv"><tbody>{cells}</tbody></table>'


def _focus_text(report: "Report") -> str:
    d = report.options.object_distance_mm
    if d is None:
        return f"the lens file's object distance ({report.summary.get('object', '?')})"
    return "infinity" if math.isinf(d) else f"{d / 1000:g} m from the first vertex"


def render_html(report: "Report") -> str:
    """The whole page as a string."""
    o = report.options
    q = o.preset
    s = report.summary
    n_ok = sum(1 for sec in report.sections if sec.ok and not sec.data.get("skipped"))
    skipped = [sec for sec in report.sections if sec.data.get("skipped")]
    if report.failed:
        status = (f'<div class="status bad">{len(report.failed)} of {len(report.sections) - len(skipped)} sections '
                  "failed: " + "; ".join(f"{_e(sec.title)} ({_e(sec.errors[0])})" for sec in report.failed)
                  + ". Each says what went wrong below; the rest of the report stands.</div>")
    else:
        status = (f'<div class="status ok">All {n_ok} sections made'
                  + (f" ({len(skipped)} skipped)" if skipped else "") + f" in {report.seconds:.0f} s.</div>")
    fno = f"f/{o.f_number:g} (stopped down)" if o.f_number else f"f/{s['f_number']:.3g} (the lens file's)"
    facts = [("lens file", str(s.get("lens_file") or s.get("path") or "-")), ("sensor", o.sensor),
             ("focus", _focus_text(report)), ("aperture", fno),
             ("quality", f"{o.quality}: compare {q.compare_rays:,} rays per field, PSF map {q.psf_grid[0]} x "
                         f"{q.psf_grid[1]} x {q.psf_rays:,} rays, MTF {q.mtf_fields} heights x {q.mtf_rays:,} rays, "
                         f"bokeh {q.bokeh_grid[0]} x {q.bokeh_grid[1]} cells x 2 sources x {q.bokeh_rays:,} rays"
                         + (f"; time budget {o.time_budget_s:g} s for PSF and MTF" if o.time_budget_s else "")),
             ("device", report.device_name),
             ("precision", f"{o.precision} Monte Carlo kernels (PSF, MTF, bokeh); float64 for the paraxial-against-"
                           "real analyses"),
             ("seed", str(o.seed)), ("made", f"{report.environment['date_utc']} in {report.seconds:.1f} s by lensrt "
                                             f"{report.environment['lensrt']}")]
    toc = []
    for i, sec in enumerate(report.sections, 1):
        mark = ('<span class="mark skip">skipped</span>' if sec.data.get("skipped") else
                '<span class="mark ok">\u2713</span>' if sec.ok else '<span class="mark bad">failed</span>')
        toc.append(f'<li><a href="#{sec.key}">{_e(sec.title)}</a>{mark}</li>')
    toc.append('<li><a href="#monte-carlo">Monte Carlo figures: samples, run time, standard error</a></li>')
    toc.append('<li><a href="#run">How this report was made</a></li>')
    title = f"{s.get('efl_mm', 0):.4g} mm f/{s.get('f_number', 0):.3g}, full field {s.get('full_field', '?')}, " \
            f"{s.get('surfaces', '?')} surfaces"
    parts = [
        "<!DOCTYPE html>", '<html lang="en"><head><meta charset="utf-8">',
        '<meta name="viewport" content="width=device-width, initial-scale=1">',
        f"<title>lensrt report: {_e(report.lens_name)}</title>", f"<style>{_CSS}</style></head>",
        f'<body data-report="{"ok" if not report.failed else "failed"}" data-images="loading">',
        '<header><div class="wrap">',
        f"<h1>{_e(report.lens_name)}<small>lensrt lens report</small></h1>",
        f'<p class="sub">{_e(title)}</p>', status, _keys_html(report),
        '<div class="top">', _kv(facts),
        f'<nav><strong>Contents</strong><ol>{"".join(toc)}</ol></nav>', "</div>",
        "</div></header>", '<main class="wrap">',
    ]
    for i, sec in enumerate(report.sections, 1):
        parts.append(f'<section id="{sec.key}"><h2><span class="n">{i}.</span>{_e(sec.title)}</h2>')
        if sec.data.get("skipped"):
            parts.append("<p>Skipped (<code>--skip</code>).</p></section>")
            continue
        for err in sec.errors:
            parts.append(f'<div class="error"><strong>This section failed:</strong> {_e(err)}</div>')
        parts.append(_blocks(sec.blocks))
        for w in sec.warnings:
            parts.append(f'<p class="warn">Warning: {_e(w)}</p>')
        parts.append(f'<p class="sub" style="font-size:13px">Section made in {sec.seconds:.1f} s.</p></section>')
    parts.append(_monte_carlo_html(report))
    parts.append(_run_html(report))
    parts.append('<footer>Made by lensrt; physics after the <i>Field Guide to Photographic Science</i> '
                 "(Rowlands, SPIE 2020), page numbers as cited. Every file named here lies beside this page.</footer>")
    parts.append(f"</main><script>{_SCRIPT}</script></body></html>")
    return "\n".join(parts) + "\n"


def _keys_html(report: "Report") -> str:
    cards = "".join(f'<a class="key" href="#{html.escape(k["section"], quote=True)}"><span class="kl">{_e(k["label"])}'
                    f'</span><span class="kval">{_e(k["value"])}</span><span class="kn">{_e(k["note"])}</span></a>'
                    for k in report.key_numbers)
    return f'<div class="keys">{cards}</div>' if cards else ""


def _monte_carlo_html(report: "Report") -> str:
    rows = [[m["figure"], m["quantity"], f"{m['samples']:,}", m["seconds"], m["stderr"], m["method"]]
            for m in report.monte_carlo]
    t = Table(rows, ["figure", "quantity", "samples", "seconds", "standard error", "how"], digits=2)
    return ('<section id="monte-carlo"><h2>Monte Carlo figures: samples, run time, standard error</h2>'
            "<p>Every Monte Carlo number in this report carries its sample count, the seconds it took and a standard "
            "error from independent batches (batch means, or the jackknife for non-linear quantities); see each "
            "figure's caption and the tables for per-field values.</p>"
            + (html_table(t) if rows else "<p>No Monte Carlo figure was made.</p>") + "</section>")


def _run_html(report: "Report") -> str:
    env = report.environment
    o = report.options
    cmd = html.escape(env.get("command_line") or "(called from Python)")
    rows = [("command line", f'<div class="cmd">{cmd}</div>'),
            ("lensrt", env["lensrt"]), ("python", env["python"]), ("numpy", str(env.get("numpy"))),
            ("warp", str(env.get("warp"))), ("matplotlib", str(env.get("matplotlib"))),
            ("platform", env["platform"]), ("device", report.device_name),
            ("precision", o.precision), ("seed", str(o.seed)), ("total run time", f"{report.seconds:.1f} s")]
    for n in report.lens_notes:
        rows.append(("lens changed", n))
    times = Table([[sec.title, "skipped" if sec.data.get("skipped") else ("ok" if sec.ok else "failed"),
                    sec.seconds] for sec in report.sections], ["section", "outcome", "seconds"], digits=1)
    return ('<section id="run"><h2>How this report was made</h2>' + _kv(rows, raw=frozenset({"command line"}))
            + html_table(times)
            + '<ul class="files"><li><a href="report.json"><code>report.json</code></a> \u2014 everything on this page '
              "and more (all tables' data, the full paraxial-against-real comparison, every Monte Carlo record, "
              "options, environment, errors)</li></ul></section>")


def write_html(report: "Report", path: str | Path) -> Path:
    """Write :func:`render_html` to ``path``."""
    p = Path(path)
    p.write_text(render_html(report), encoding="utf-8")
    return p
