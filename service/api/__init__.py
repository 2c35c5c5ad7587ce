"""The REST API of softevo (docs/spec.md section 6): ``create_app`` in ``service.api.app``,
routes in ``service.api.routes``, request and response schemas in ``service.api.schemas``."""
