"""umlbot studio: the browser page that shows a model's diagrams and follows the robot live.

`umlbot.studio.server` serves one page (built assets in `umlbot/studio/static/`, sources in
`umlbot/studio/web/`) and one WebSocket carrying the model as JSON (`model_view`) and the robot's
traffic as `MonitorEvent`s (the same events `umlbot monitor --json` prints).
"""
