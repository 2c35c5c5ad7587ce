"""The REST API of softevo (SPEC.md section 6): ``create_app`` in ``service.api.app``,
routes in ``service.api.routes``, request and response schemas in ``service.api.schemas``."""
