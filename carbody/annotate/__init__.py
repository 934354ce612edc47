"""Mark a photo in minutes: a local page that asks one keypoint at a time and fits the car live.

    from carbody.annotate import AnnotationSession, serve
    session = AnnotationSession("car.jpg", output="car.json")   # -k marks.json to start from
    serve(session, port=0)                                        # what ``carbody annotate`` does
    session.place("nose_centre", (283.5, 310.1))                  # or drive it from Python
    session.state()["fit"]["ghosts"]                              # where the car puts the rest
    session.save()

Modules, one role each: :mod:`~carbody.annotate.marks` (the marks, the files they are saved
to), :mod:`~carbody.annotate.live_fit` (the quick and the full fit and what the page draws of
them), :mod:`~carbody.annotate.guide` (which keypoint to ask next),
:mod:`~carbody.annotate.session` (one photo being marked: everything the page does),
:mod:`~carbody.annotate.worker` (the full fit's process), :mod:`~carbody.annotate.server` (the
standard library's HTTP server, 127.0.0.1 only) and ``static/`` (the page: HTML, one script,
one style sheet; nothing fetched from elsewhere), :mod:`~carbody.annotate.browser` (driving it
in headless Chromium), :mod:`~carbody.annotate.cli` (``carbody annotate``). docs/annotate.md
describes the page.
"""
__all__ = ["AnnotationSession", "serve"]


def __getattr__(name: str):
    # lazily: ``carbody --help`` imports this package's command without its server and fits
    if name == "AnnotationSession":
        from carbody.annotate.session import AnnotationSession

        return AnnotationSession
    if name == "serve":
        from carbody.annotate.server import serve

        return serve
    raise AttributeError(f"module 'carbody.annotate' has no attribute {name!r}")
