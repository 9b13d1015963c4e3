"""sanlab studio: a local web studio over the gait library (runs, gaits, playback, live mode).

Layers, top to bottom: ``server`` (uvicorn), ``app`` (Starlette routes and the WebSocket
protocol), ``service`` (the one module that calls into the rest of sanlab), ``static/`` (the
page: plain ES modules and canvas, no build step); ``bench`` measures live mode. The `sanlab
studio` command is :mod:`sanlab.cli.studio`, the only other module of sanlab that imports this
package, so this package needs no Typer.
"""
