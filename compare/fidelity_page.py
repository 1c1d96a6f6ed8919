"""The outputs of ``pbrcheck fidelity``: ``fidelity.csv``, ``fidelity.json`` and the page ``index.html``.

The page: the settings and the run's wall time; the cases where RF's -22 dB verdict and the truth's
disagree; per scenario and renderer the error against the truth with its noise flags (relmse, FLIP,
Delta E ITP; per material where the scene has several) beside RF's score against the three.js image
and both verdicts (``not modelled`` where the scene uses a feature pbrcheck does not model: no
verdict); per engine (with its wall time, CPU time and peak memory) and per extension summaries; and
"which path tracer is right" per asset. Every name from the config or the assets goes through
:func:`pbrcheck.fmt.xml_text` and :func:`html.escape` (HTML) or :func:`pbrcheck.fmt.csv_cell` (CSV).

API: :func:`engine_summary`, :func:`extension_summary`, :func:`path_tracer_table`,
:func:`disagreements`, :func:`render_page`, :func:`write_outputs`.
"""

from __future__ import annotations

import html
import statistics
from pathlib import Path

from pbrcheck.atomic import write_text_atomic
from pbrcheck.fmt import xml_text as _xml_text
from pbrcheck.jsonio import dump_json

from .corpus.outputs import write_csv
from .fidelity import METRIC_NAMES, PATH_TRACERS, RF_BASELINE, RF_THRESHOLD_DB, ROW_COLUMNS, TRUTH_FLIP_PASS

def xml_text(s) -> str:
    """``s`` for HTML text and attributes: XML-illegal characters made visible
    (:func:`pbrcheck.fmt.xml_text`), then the markup characters escaped."""
    return html.escape(_xml_text(str(s)), quote=True)


#: The truth's own line in the per-engine table.
TRUTH_NAME = "reference (truth, path mode)"
NOT_MODELLED = "not modelled"


def _median(values):
    v = [x for x in values if isinstance(x, (int, float))]
    return statistics.median(v) if v else None


def _sum(values):
    v = [x for x in values if isinstance(x, (int, float))]
    return sum(v) if v else None


def _max(values):
    v = [x for x in values if isinstance(x, (int, float))]
    return max(v) if v else None


def disagreements(rows: list[dict]) -> list[dict]:
    """The rows whose RF verdict and truth verdict differ (judged rows only)."""
    return [r for r in rows if r.get("disagree")]


def engine_summary(rows: list[dict], renderer_names: list[str]) -> list[dict]:
    """Per renderer: rows, errors, not-modelled rows, median metrics over judged rows, RF and
    truth passes, disagreements, total wall and CPU time and peak memory of its renders; then the
    truth's line (each scenario's truth counted once)."""
    out = []
    for name in renderer_names:
        rs = [r for r in rows if r["renderer"] == name]
        ok = [r for r in rs if r["status"] == "ok"]
        judged = [r for r in ok if not r.get("not_modelled")]
        out.append({
            "renderer": name, "rows": len(rs), "errors": len(rs) - len(ok),
            "not_modelled": len(ok) - len(judged),
            **{m: _median(r.get(m) for r in judged) for m in METRIC_NAMES},
            "rf_db": _median(r.get("rf_db") for r in judged),
            "rf_pass": sum(1 for r in judged if r.get("rf_pass")),
            "rf_judged": sum(1 for r in judged if r.get("rf_pass") is not None),
            "truth_pass": sum(1 for r in judged if r.get("truth_pass")),
            "judged": len(judged), "disagree": sum(1 for r in judged if r.get("disagree")),
            "wall_s": _sum(r.get("wall_s") for r in ok), "cpu_s": _sum(r.get("cpu_s") for r in ok),
            "peak_mib": _max(r.get("peak_mib") for r in ok)})
    truth = {}
    for r in rows:
        if r["status"] == "ok" and r["scenario"] not in truth:
            truth[r["scenario"]] = r
    t = list(truth.values())
    out.append({"renderer": TRUTH_NAME, "rows": len(t), "errors": None, "not_modelled": None,
                "wall_s": _sum(r.get("truth_wall_s") for r in t), "cpu_s": _sum(r.get("truth_cpu_s") for r in t),
                "peak_mib": _max(r.get("truth_peak_mib") for r in t)})
    return out


def extension_summary(rows: list[dict], renderer_names: list[str]) -> list[dict]:
    """Per glTF extension used by the scenarios (``core`` for none) and renderer: judged rows,
    median FLIP, RF and truth passes; ``not_modelled`` rows counted apart."""
    exts: dict[str, list[dict]] = {}
    for r in rows:
        for e in [x.strip() for x in (r.get("extensions") or "").split(",") if x.strip()] or ["core"]:
            exts.setdefault(e, []).append(r)
    out = []
    for e in sorted(exts):
        for name in renderer_names:
            rs = [r for r in exts[e] if r["renderer"] == name and r["status"] == "ok"]
            judged = [r for r in rs if not r.get("not_modelled")]
            out.append({"extension": e, "renderer": name, "judged": len(judged),
                        "not_modelled": len(rs) - len(judged),
                        "flip_mean": _median(r.get("flip_mean") for r in judged),
                        "rf_pass": sum(1 for r in judged if r.get("rf_pass")),
            "rf_judged": sum(1 for r in judged if r.get("rf_pass") is not None),
                        "truth_pass": sum(1 for r in judged if r.get("truth_pass"))})
    return out


def path_tracer_table(rows: list[dict], renderer_names: list[str]) -> list[dict]:
    """Per scenario: each of RF's path tracers run here (FLIP and relmse against pbrcheck's
    reference) and the one closest to it by FLIP (``not modelled``: no pick)."""
    tracers = [t for t in PATH_TRACERS if t in renderer_names]
    out = []
    if not tracers:
        return out
    for scen in dict.fromkeys(r["scenario"] for r in rows):
        rs = {r["renderer"]: r for r in rows if r["scenario"] == scen}
        entry = {"scenario": scen, "tracers": {}}
        nm = any(r.get("not_modelled") for r in rs.values())
        for t in tracers:
            r = rs.get(t)
            entry["tracers"][t] = (None if r is None or r["status"] != "ok"
                                   else {"flip_mean": r.get("flip_mean"), "relmse": r.get("relmse"),
                                         "within_noise": bool(r.get("flip_mean_noise"))})
        scored = [(v["flip_mean"], t) for t, v in entry["tracers"].items() if v and v["flip_mean"] is not None]
        entry["closest"] = NOT_MODELLED if nm else (min(scored)[1] if scored else None)
        out.append(entry)
    return out


def _fmt(v, digits=4) -> str:
    if v is None:
        return ""
    if isinstance(v, bool):
        return "yes" if v else "no"
    if isinstance(v, float):
        return f"{v:.{digits}g}"
    return xml_text(str(v))


def _metric_cell(r: dict, m: str) -> str:
    v = r.get(m)
    if v is None:
        return "<td></td>"
    flag = " <span class='noise' title='within the reference noise'>~n</span>" if r.get(f"{m}_noise") else ""
    return f"<td>{_fmt(v)}{flag}</td>"


def _verdict(v) -> str:
    return {True: "<span class='pass'>pass</span>", False: "<span class='fail'>fail</span>"}.get(v, "")


def _table(head: list[str], body: list[str]) -> str:
    return ("<table><tr>" + "".join(f"<th>{h}</th>" for h in head) + "</tr>\n" + "\n".join(body) + "</table>\n")


def render_page(result, summaries: dict, config: str, scheduler: str) -> str:
    """The HTML page of a finished run (see the module docstring)."""
    st = result.settings
    rows = result.rows
    p = ["<!doctype html><html><head><meta charset='utf-8'><title>pbrcheck fidelity</title><style>",
         "body{font-family:sans-serif;margin:1.5em}table{border-collapse:collapse;margin:.5em 0 1.5em}"
         "td,th{border:1px solid #ccc;padding:2px 6px;text-align:right}th{background:#eee}"
         "td:first-child,td:nth-child(2){text-align:left}.pass{color:#070}.fail{color:#b00}"
         ".nm{color:#a60}.noise{color:#06a}.dis{background:#fee}.err{color:#b00;text-align:left}",
         "</style></head><body>",
         "<h1>Render Fidelity against a ground truth</h1>",
         f"<p>Config <code>{xml_text(config)}</code>: {len(result.scenarios)} scenario(s) x "
         f"{len(st.renderers)} renderer(s) ({xml_text(', '.join(r.text for r in st.renderers))}); truth: "
         f"pbrcheck's reference, <code>path</code> mode, {st.spp} spp (seed {st.seed}); image size: "
         f"{'longer side ' + str(st.size) + ' px' if st.size else 'the scenarios own'}; scheduler "
         f"{xml_text(scheduler)}; this invocation: {result.wall_s:.0f} s wall ({result.computed} row(s) computed, "
         "the rest resumed).</p>",
         f"<p>RF's verdict: its own metric (RMS of pixelmatch's YIQ difference over covered pixels, in dB, "
         f"8-bit Khronos PBR Neutral images; compare/fidelity.py cites the code) against "
         f"<code>{xml_text(RF_BASELINE)}</code>, pass at or below {RF_THRESHOLD_DB:g} dB. The truth's "
         f"verdict: mean HDR-FLIP against the reference at most {TRUTH_FLIP_PASS:g}, or every metric within "
         "the reference's noise (<span class='noise'>~n</span>). Scenes using a feature pbrcheck does not "
         f"model are marked <span class='nm'>{NOT_MODELLED}</span> and get no verdict.</p>"]
    ok = [r for r in rows if r["status"] == "ok"]
    truth = {r["scenario"]: r for r in ok}
    wall = (_sum(r.get("wall_s") for r in ok) or 0.0) + (_sum(r.get("truth_wall_s") for r in truth.values()) or 0.0)
    cpu = (_sum(r.get("cpu_s") for r in ok) or 0.0) + (_sum(r.get("truth_cpu_s") for r in truth.values()) or 0.0)
    p.append(f"<p>The rows' renders (this run's and resumed ones; the truth once per scenario, error rows not "
             f"counted): {wall:.0f} s wall, {cpu:.0f} s CPU, {wall / max(len(truth), 1):.0f} s wall per "
             "scenario.</p>")
    dis = disagreements(rows)
    p.append(f"<h2>RF and the truth disagree ({len(dis)})</h2>")
    if dis:
        p.append("<ul>" + "".join(
            f"<li><b>{xml_text(r['scenario'])}</b> / {xml_text(r['renderer'])}: RF "
            f"{'passes' if r['rf_pass'] else 'fails'} it ({_fmt(r['rf_db'])} dB), the truth "
            f"{'passes' if r['truth_pass'] else 'fails'} it (FLIP {_fmt(r['flip_mean'])})</li>" for r in dis) + "</ul>")
    else:
        p.append("<p>None.</p>")
    p.append("<h2>Per scenario and renderer</h2>")
    body = []
    for r in rows:
        nm = r.get("not_modelled")
        cls = " class='dis'" if r.get("disagree") else ""
        if r["status"] != "ok":
            body.append(f"<tr><td>{xml_text(r['scenario'])}</td><td>{xml_text(r['renderer'])}</td>"
                        f"<td class='err' colspan='7'>error ({xml_text(r.get('stage') or '')}): "
                        f"{xml_text(r.get('error') or '')}</td></tr>")
            continue
        golden = "RF's golden" if r["renderer"] == RF_BASELINE else ""
        mark = f"<span class='nm' title='{xml_text(nm)}'>{NOT_MODELLED}: {xml_text(nm)}</span>" if nm else ""
        body.append(f"<tr{cls}><td>{xml_text(r['scenario'])}</td><td>{xml_text(r['renderer'])}</td>"
                    + "".join(_metric_cell(r, m) for m in METRIC_NAMES)
                    + f"<td>{_fmt(r.get('rf_db'))}</td><td>{mark or golden or _verdict(r.get('rf_pass'))}</td>"
                    f"<td>{mark or _verdict(r.get('truth_pass'))}</td><td>{_fmt(r.get('wall_s'), 3)}</td></tr>")
    p.append(_table(["scenario", "renderer", "relmse", "FLIP", "&Delta;E ITP", "RF dB", "RF verdict",
                     "truth verdict", "wall s"], body))
    mats = [r for r in rows if r["status"] == "ok" and len(r.get("materials") or []) > 1]
    if mats:
        p.append("<h2>Per material (scenes with several)</h2>")
        body = [f"<tr><td>{xml_text(r['scenario'])}</td><td>{xml_text(r['renderer'])}</td>"
                f"<td>{xml_text(m['material'])}</td><td>{m['pixels']}</td>"
                + "".join(f"<td>{_fmt(m.get(k))}</td>" for k in METRIC_NAMES) + "</tr>"
                for r in mats for m in r["materials"]]
        p.append(_table(["scenario", "renderer", "material", "pixels", "relmse", "FLIP", "&Delta;E ITP"], body))
    p.append("<h2>Per engine</h2>")
    body = [f"<tr><td>{xml_text(e['renderer'])}</td><td>{e['rows']}</td><td>{_fmt(e.get('errors'))}</td>"
            f"<td>{_fmt(e.get('not_modelled'))}</td>" + "".join(f"<td>{_fmt(e.get(m))}</td>" for m in METRIC_NAMES)
            + f"<td>{_fmt(e.get('rf_db'))}</td><td>{_fmt(e.get('rf_pass'))}/{_fmt(e.get('rf_judged'))}</td>"
            f"<td>{_fmt(e.get('truth_pass'))}/{_fmt(e.get('judged'))}</td><td>{_fmt(e.get('disagree'))}</td>"
            f"<td>{_fmt(e.get('wall_s'), 4)}</td><td>{_fmt(e.get('cpu_s'), 4)}</td><td>{_fmt(e.get('peak_mib'), 4)}</td></tr>"
            for e in summaries["engines"]]
    p.append(_table(["renderer", "rows", "errors", NOT_MODELLED, "median relmse", "median FLIP",
                     "median &Delta;E ITP", "median RF dB", "RF pass", "truth pass", "disagree",
                     "wall s (sum)", "CPU s (sum)", "peak MiB"], body))
    p.append("<p>Wall and CPU time: the sum over the renderer's renders (CPU time of the rendering process and "
             "its descendants, a browser client's node and Chromium processes included, polled every 0.1 s); peak memory: the largest resident "
             "set of the rendering process and its live children during one render, sampled every 0.1 s.</p>")
    p.append("<h2>Per extension</h2>")
    body = [f"<tr><td>{xml_text(e['extension'])}</td><td>{xml_text(e['renderer'])}</td><td>{e['judged']}</td>"
            f"<td>{e['not_modelled']}</td><td>{_fmt(e['flip_mean'])}</td><td>{e['rf_pass']}</td>"
            f"<td>{e['truth_pass']}</td></tr>" for e in summaries["extensions"]]
    p.append(_table(["extension", "renderer", "judged", NOT_MODELLED, "median FLIP", "RF pass", "truth pass"], body))
    pt = summaries["path_tracers"]
    p.append("<h2>Which path tracer is right</h2>")
    if pt:
        tracers = list(pt[0]["tracers"])
        body = []
        for e in pt:
            cells = "".join(
                "<td>error</td>" if v is None else
                f"<td>FLIP {_fmt(v['flip_mean'])}, relmse {_fmt(v['relmse'])}{' ~n' if v['within_noise'] else ''}</td>"
                for v in e["tracers"].values())
            body.append(f"<tr><td>{xml_text(e['scenario'])}</td>{cells}<td>{xml_text(e['closest'] or '')}</td></tr>")
        p.append(_table(["scenario"] + [xml_text(t) for t in tracers] + ["closest to pbrcheck's reference"], body))
        missing = [t for t in PATH_TRACERS if t not in tracers]
        if missing:
            p.append(f"<p>Not run here: {xml_text(', '.join(missing))}.</p>")
    else:
        p.append("<p>No path tracer client among the renderers.</p>")
    p.append("</body></html>\n")
    return "\n".join(p)


def write_outputs(result, config: str | Path) -> dict[str, Path]:
    """``fidelity.csv`` (:data:`compare.fidelity.ROW_COLUMNS`), ``fidelity.json`` (settings, rows with
    their per-material metrics, summaries) and ``index.html`` in ``result.out_dir``."""
    names = [r.text for r in result.settings.renderers]
    summaries = {"engines": engine_summary(result.rows, names),
                 "extensions": extension_summary(result.rows, names),
                 "path_tracers": path_tracer_table(result.rows, names),
                 "disagreements": [{"scenario": r["scenario"], "renderer": r["renderer"]}
                                   for r in disagreements(result.rows)]}
    config, scheduler = str(config), result.scheduler
    out = result.out_dir
    files = {"csv": write_csv(out / "fidelity.csv", result.rows, ROW_COLUMNS)}
    doc = {"config": config, "settings": result.settings.to_json(), "scheduler": scheduler,
           "wall_s": result.wall_s, "computed": result.computed,
           "scenarios": [{"name": s.name, "problem": s.problem, "exclude": list(s.exclude),
                          "not_modelled": list(s.not_modelled), "extensions": list(s.extensions)}
                         for s in result.scenarios],
           "rows": result.rows, "summaries": summaries}
    files["json"] = write_text_atomic(out / "fidelity.json", dump_json(doc, indent=1) + "\n")
    files["html"] = write_text_atomic(out / "index.html", render_page(result, summaries, config, scheduler))
    return files
