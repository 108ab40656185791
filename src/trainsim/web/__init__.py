"""trainsim's web application: train and route tables, runs and plots, live driving.

``create_app()`` builds the FastAPI application; ``trainsim serve`` runs it with uvicorn. See
docs/WEB.md.
"""

from trainsim.web.app import create_app
from trainsim.web.config import WebSettings

__all__ = ["WebSettings", "create_app"]
