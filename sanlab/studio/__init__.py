"""sanlab studio: a local web studio over the gait library (runs, gaits, playback, live mode).

Layers, top to bottom: ``command`` (the `sanlab studio` command), ``server`` (uvicorn),
``app`` (Starlette routes and the WebSocket protocol), ``service`` (the one module that calls
into the rest of sanlab), ``static/`` (the page: plain ES modules and canvas, no build step).
Nothing else in sanlab imports this package.
"""
