"""The clinician's dashboard: static page (index.html, app.js, style.css) and its HTTP + websocket server."""
