"""The read-only web app over a ``Store`` (FastAPI + Jinja2; plots by plotly.js).

Pages: ``/`` (runs, filtered and paged; running runs refresh themselves), ``/runs/{id}``
(time plots decimated on the server, fits, limits, trips, drops, run.json, downloads),
``/compare?runs=a,b`` (static curves and step responses overlaid), ``/constants``,
``/benches?motor=M&propeller=P`` (every bench's constants of one actuator, E_n of every
pair: ``bench.store.bench_comparison``). The
same data as JSON under ``/api/``; the OpenAPI description is ``/openapi.json``.

A run id is only ever looked up in the store (``Store.run_folder``) and must be one
(``bench.engine.run_ids.is_run_id``, the same test the stores apply to ids they read from
run folders and catalog rows): no path is built from a request, so ``../`` and friends
have nothing to reach. The store's SQL binds every value. A folder store is opened
read-only: the app never writes.
"""

from __future__ import annotations

import functools
import io
import json
import math
import re
import time
from dataclasses import replace
from pathlib import Path
from typing import Annotated, Any

from fastapi import FastAPI, HTTPException, Query, Request
from fastapi.responses import (
    FileResponse,
    HTMLResponse,
    JSONResponse,
    RedirectResponse,
    Response,
    StreamingResponse,
)
from fastapi.templating import Jinja2Templates

from analysis.errors import LogError
from bench.engine.run_ids import is_run_id
from bench.errors import RigError
from bench.serve.run_views import (
    RecordCache,
    SeriesCache,
    calibration_view,
    command_edges,
    export_of,
    fits_of,
    static_points,
    step_traces,
)
from bench.serve.security import COOKIE, Guard, token_matches
from bench.store.bench_comparison import NothingToCompare, compare_benches
from bench.store.json_values import finite_number, json_safe
from bench.store.run_summary import BadFilter, RunFilter, RunSummary
from bench.store.stores import FolderStore, Store

__all__ = ["create_app"]

HERE = Path(__file__).parent
PAGE_SIZES = (25, 50, 100, 200)
PLOT_COLUMNS = 1500  # min/max bins per time plot: about one per pixel column of a wide page
EXPORTS = ("ardupilot", "px4", "gazebo")
LOG_TAIL_BYTES = 64 * 1024  # the end of run.log shown on a run's page (the file: a link)
Text = Annotated[str | None, Query(max_length=128)]


def _plotly_js() -> Path:
    import plotly

    return Path(plotly.__file__).parent / "package_data" / "plotly.min.js"


def create_app(store: Store, *, token: str | None = None, title: str = "rotorbench") -> Any:
    """The ASGI app (wrapped in the guard) serving ``store``."""
    app = FastAPI(title=f"{title} runs", version="1", docs_url=None, redoc_url=None)
    templates = _templates()
    cache = RecordCache()
    series_cache = SeriesCache()
    if isinstance(store, FolderStore) and not store.read_only:
        store = replace(store, read_only=True)
    app.state.store = store

    def run_or_404(run_id: str) -> Path:
        if not is_run_id(run_id):
            raise HTTPException(404, f"no run {run_id[:64]!r}")
        try:
            return store.run_folder(run_id)
        except RigError:
            raise HTTPException(404, f"no run {run_id!r}") from None

    def record_of(run_id: str) -> Any:
        try:
            return cache.get(run_or_404(run_id))
        except LogError as exc:
            raise HTTPException(422, f"run {run_id}: {exc}") from None

    def filters(bench: str | None, motor: str | None, propeller: str | None,
                esc_mode: str | None, sequence: str | None, status: str | None,
                since: str | None, until: str | None) -> RunFilter:
        """The page's filters; a date that is not one is ``BadFilter``, answered 422."""
        return RunFilter(bench=bench or None, status=status or None, sequence=sequence or None,
                         motor=motor or None, propeller=propeller or None,
                         esc_mode=esc_mode or None, since=since or None, until=until or None)

    # -- JSON ----------------------------------------------------------------------------
    @app.get("/api/runs", summary="runs, newest first, filtered and paged")
    def api_runs(response: Response, bench: Text = None, motor: Text = None,
                 propeller: Text = None, esc_mode: Text = None, sequence: Text = None,
                 status: Text = None, since: Text = None, until: Text = None,
                 limit: Annotated[int, Query(ge=1, le=1000)] = 100,
                 offset: Annotated[int, Query(ge=0, le=10_000_000)] = 0) -> list[dict[str, Any]]:
        where = filters(bench, motor, propeller, esc_mode, sequence, status, since, until)
        response.headers["X-Total-Count"] = str(store.count_runs(where))
        return [_row(r) for r in store.list_runs(where, limit=limit, offset=offset)]

    @app.get("/api/runs/{run_id}", summary="one run: its run.json")
    def api_run(run_id: str) -> dict[str, Any]:
        rec = record_of(run_id)
        return {"run_id": rec.id, "meta": json_safe(rec.meta), "rows": len(rec.samples),
                "columns": [str(c) for c in rec.samples.columns]}

    @app.get("/api/runs/{run_id}/series", summary="time plots, min/max per pixel column")
    def api_series(run_id: str, columns: Annotated[int, Query(ge=10, le=10000)] = 1500
                   ) -> dict[str, Any]:
        try:
            return series_cache.get(run_or_404(run_id), columns)
        except LogError as exc:
            raise HTTPException(422, f"run {run_id}: {exc}") from None

    @app.get("/api/runs/{run_id}/fits", summary="step fit and static curves of a run")
    def api_fits(run_id: str) -> dict[str, Any]:
        return fits_of(record_of(run_id))

    @app.get("/api/compare", summary="static curves and step responses of several runs")
    def api_compare(runs: Annotated[str, Query(max_length=1200)]) -> dict[str, Any]:
        ids = [r for r in runs.split(",") if r][:12]
        if not ids:
            raise HTTPException(422, "runs: give run ids separated by commas")
        recs = [record_of(r) for r in ids]
        edges = [command_edges(r) for r in recs]  # each run's jumps found once
        return {"static": [static_points(r, edges=e) for r, e in zip(recs, edges, strict=True)],
                "steps": [step_traces(r, edges=e) for r, e in zip(recs, edges, strict=True)]}

    @app.get("/api/constants", summary="measured constants with their provenance")
    def api_constants() -> list[dict[str, Any]]:
        return [json_safe(c.__dict__) for c in store.constants()]

    @app.get("/api/benches", summary="every bench's constants of one actuator, E_n of "
                                     "every pair (ISO/IEC 17043)")
    def api_benches(motor: Annotated[str, Query(max_length=128)],
                    propeller: Annotated[str, Query(max_length=128)], esc: Text = None,
                    esc_mode: Text = None, battery: Text = None) -> dict[str, Any]:
        try:
            result = compare_benches(store, motor, propeller, esc=esc or None,
                                     esc_mode=esc_mode or None, battery=battery or None)
        except NothingToCompare as exc:
            raise HTTPException(422, str(exc)) from None
        return json_safe(result.as_dict())

    @app.get("/api/live", summary="running runs: status, elapsed time, latest values")
    def api_live() -> list[dict[str, Any]]:
        out = []
        for r in store.list_runs(RunFilter(status="running"), limit=50):
            row = _row(r) | {"elapsed_s": _elapsed(r.started_utc), "latest": {}}
            try:
                rec = cache.get(run_or_404(r.run_id))
                last = rec.samples.iloc[-1]
                row["latest"] = {k: finite_number(last[k]) for k in ("t_s", "thrust_n", "current_a",
                                                            "rpm") if k in last.index}
            except (HTTPException, LogError):
                pass  # recorded elsewhere, no part written yet, or not a run id
            out.append(row)
        return out

    # -- downloads -----------------------------------------------------------------------
    @app.get("/runs/{run_id}/run.json")
    def download_meta(run_id: str) -> FileResponse:
        from analysis.run_paths import read_run_json

        folder = run_or_404(run_id)
        try:  # a run.json that is a link out of its folder, or no JSON object, is not sent
            read_run_json(folder)
        except LogError as exc:
            raise HTTPException(422, f"run {run_id}: {exc}") from None
        return FileResponse(folder / "run.json", media_type="application/json",
                            filename=f"{run_id}.json")

    @app.get("/runs/{run_id}/run.log")
    def download_log(run_id: str) -> FileResponse:
        from analysis.run_paths import log_path

        folder = run_or_404(run_id)
        try:  # a run.log that is a link out of its folder is not sent
            path = log_path(folder)
        except LogError as exc:
            raise HTTPException(422, f"run {run_id}: {exc}") from None
        if path is None:
            raise HTTPException(404, f"run {run_id}: no run.log (recorded before it existed, "
                                "or imported)")
        return FileResponse(path, media_type="text/plain; charset=utf-8",
                            filename=f"{run_id}.log")

    @app.get("/runs/{run_id}/calibration.png")
    def download_calibration_figure(run_id: str) -> FileResponse:
        from analysis.run_paths import member

        folder = run_or_404(run_id)
        try:  # a figure that is a link out of its folder is not sent
            path = member(folder, "calibration.png", "the calibration's figure")
        except LogError as exc:
            raise HTTPException(422, f"run {run_id}: {exc}") from None
        if not path.is_file():
            raise HTTPException(404, f"run {run_id}: no calibration figure")
        return FileResponse(path, media_type="image/png")

    @app.get("/runs/{run_id}/samples.parquet")
    def download_parquet(run_id: str) -> Response:
        buf = io.BytesIO()
        record_of(run_id).samples.to_parquet(buf, index=False)
        return Response(buf.getvalue(), media_type="application/vnd.apache.parquet",
                        headers=_attachment(f"{run_id}.parquet"))

    @app.get("/runs/{run_id}/samples.csv")
    def download_csv(run_id: str) -> StreamingResponse:
        df = record_of(run_id).samples

        def chunks() -> Any:
            for start in range(0, max(len(df), 1), 200_000):
                yield df.iloc[start:start + 200_000].to_csv(index=False, header=start == 0)
        return StreamingResponse(chunks(), media_type="text/csv",
                                 headers=_attachment(f"{run_id}.csv"))

    @app.get("/runs/{run_id}/export/{target}")
    def download_export(run_id: str, target: str) -> Response:
        if target not in EXPORTS:
            raise HTTPException(404, f"no export {target[:20]!r} (ardupilot, px4, gazebo)")
        try:
            out = export_of(record_of(run_id), target)
        except (LogError, RigError) as exc:
            raise HTTPException(422, f"export {target}: {exc}") from None
        return Response(json.dumps(out, indent=2), media_type="application/json",
                        headers=_attachment(f"{run_id}-{target}.json"))

    # -- pages ---------------------------------------------------------------------------
    @app.get("/", response_class=HTMLResponse, include_in_schema=False)
    def page_runs(request: Request, bench: Text = None, motor: Text = None,
                  propeller: Text = None, esc_mode: Text = None, sequence: Text = None,
                  status: Text = None, since: Text = None, until: Text = None,
                  page: Annotated[int, Query(ge=1, le=1_000_000)] = 1,
                  per_page: Annotated[int, Query(ge=1, le=200)] = 50) -> Any:
        where = filters(bench, motor, propeller, esc_mode, sequence, status, since, until)
        total = store.count_runs(where)
        runs = store.list_runs(where, limit=per_page, offset=(page - 1) * per_page)
        params = {k: v for k, v in where.__dict__.items() if v}
        return templates.TemplateResponse(request, "runs.html", {
            "runs": [_row(r) for r in runs], "total": total, "page": page,
            "per_page": per_page, "pages": max(1, math.ceil(total / per_page)),
            "filters": params, "store": store.describe(), "title": title})

    @app.get("/runs/{run_id}", response_class=HTMLResponse, include_in_schema=False)
    def page_run(request: Request, run_id: str) -> Any:
        from analysis.run_paths import read_log_tail
        from analysis.run_record import read_meta, sample_count

        folder = run_or_404(run_id)
        try:  # the page needs the metadata; the samples come with the plots
            meta = read_meta(folder)
            rows = sample_count(folder, meta)
        except LogError as exc:
            raise HTTPException(422, f"run {run_id}: {exc}") from None
        try:
            log_text = read_log_tail(folder, LOG_TAIL_BYTES)
        except LogError as exc:  # a link out of the folder: said, not followed
            log_text = str(exc)
        return templates.TemplateResponse(request, "run.html", {
            "run_id": str(meta.get("id") or run_id), "meta": meta, "rows": rows,
            "title": title,
            "meta_text": json.dumps(json_safe(_short_meta(meta)), indent=2),
            "limits": meta.get("limits") or {}, "trip": meta.get("trip"),
            "drops": {k: meta.get(k) for k in ("dropped_samples", "longest_gap_s", "drops",
                                               "link_errors") if meta.get(k) is not None},
            "exports": EXPORTS, "columns": PLOT_COLUMNS, "log_text": log_text,
            "calibration": calibration_view(meta)})

    @app.get("/compare", response_class=HTMLResponse, include_in_schema=False)
    def page_compare(request: Request, runs: Annotated[str, Query(max_length=1200)] = ""
                     ) -> Any:
        ids = [r for r in runs.split(",") if r][:12]
        for r in ids:
            run_or_404(r)
        return templates.TemplateResponse(request, "compare.html", {
            "runs": ids, "runs_param": ",".join(ids), "title": title})

    @app.get("/constants", response_class=HTMLResponse, include_in_schema=False)
    def page_constants(request: Request) -> Any:
        rows = store.constants()
        return templates.TemplateResponse(request, "constants.html", {
            "rows": rows, "store": store.describe(), "title": title})

    @app.get("/benches", response_class=HTMLResponse, include_in_schema=False)
    def page_benches(request: Request, motor: Text = None, propeller: Text = None,
                     esc: Text = None, esc_mode: Text = None, battery: Text = None) -> Any:
        asked = {k: v for k, v in (("motor", motor), ("propeller", propeller), ("esc", esc),
                                   ("esc_mode", esc_mode), ("battery", battery)) if v}
        result, why = None, ""
        if motor and propeller:
            try:
                result = compare_benches(store, motor, propeller, esc=esc or None,
                                         esc_mode=esc_mode or None, battery=battery or None)
            except NothingToCompare as exc:
                why = str(exc)
        pairs = {(r.motor, r.propeller) for r in store.constants()}
        return templates.TemplateResponse(request, "benches.html", {
            "asked": asked, "result": result, "why": why, "title": title,
            "store": store.describe(), "stored": sorted(pairs)},
            status_code=422 if why else 200)

    @app.get("/login", include_in_schema=False)
    def login(given: Annotated[str, Query(alias="token", max_length=512)] = "") -> Response:
        """The cookie is set only for the server's token: a wrong one is 401, no cookie."""
        if token is not None and not token_matches(given.encode(), token):
            raise HTTPException(401, "wrong token")
        resp = RedirectResponse("/", status_code=303)
        if token is not None:
            resp.set_cookie(COOKIE, given, httponly=True, samesite="strict")
        return resp

    @app.get("/static/plotly.min.js", include_in_schema=False)
    def plotly_js() -> FileResponse:
        return FileResponse(_plotly_js(), media_type="text/javascript",
                            headers={"Cache-Control": "public, max-age=86400"})

    @app.get("/static/{name}", include_in_schema=False)
    def static(name: str) -> FileResponse:
        files = {p.name: p for p in (HERE / "static").iterdir()}
        if name not in files:
            raise HTTPException(404, "no such file")
        return FileResponse(files[name])

    @app.exception_handler(RigError)
    def store_error(request: Request, exc: RigError) -> JSONResponse:
        """A filter that is not valid is the request's fault (422); any other store
        error is the store's (503)."""
        return JSONResponse({"detail": str(exc)},
                            status_code=422 if isinstance(exc, BadFilter) else 503)

    return Guard(app, token)


@functools.cache
def _templates() -> Jinja2Templates:
    """The pages, compiled once per process and shared by every app made in it (an app
    sets nothing on them; compiling them was two thirds of ``create_app``)."""
    templates = Jinja2Templates(directory=str(HERE / "templates"))
    _warm(templates)
    return templates


def _warm(templates: Any) -> None:
    """Compile the pages and import the readers now, not on a user's first click."""
    import pyarrow.dataset
    import pyarrow.parquet  # noqa: F401

    import analysis.run_record  # noqa: F401

    for name in ("runs.html", "run.html", "compare.html", "constants.html", "benches.html"):
        templates.env.get_template(name)


def _row(r: RunSummary) -> dict[str, Any]:
    d = r.as_dict()
    d["duration_s"] = _duration(r.started_utc, r.ended_utc)
    return json_safe(d)


def _parse(ts: str | None) -> float | None:
    from datetime import datetime

    if not ts:
        return None
    try:
        return datetime.fromisoformat(ts.replace("Z", "+00:00")).timestamp()
    except ValueError:
        return None


def _duration(start: str | None, end: str | None) -> float | None:
    a, b = _parse(start), _parse(end)
    return None if a is None or b is None else round(b - a, 3)


def _elapsed(start: str | None) -> float | None:
    a = _parse(start)
    return None if a is None else round(time.time() - a, 1)


def _short_meta(meta: dict[str, Any]) -> dict[str, Any]:
    """run.json without the long plan lists (they are in the download)."""
    return {k: (f"[{len(v)} entries: download run.json]" if isinstance(v, list) and len(v) > 40
                else v) for k, v in meta.items()}


def _attachment(name: str) -> dict[str, str]:
    safe = re.sub(r"[^A-Za-z0-9_.+-]", "_", name)
    return {"Content-Disposition": f'attachment; filename="{safe}"'}
