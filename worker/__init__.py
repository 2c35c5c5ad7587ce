if __name__ != "softevo.worker":  # installed as softevo.worker (pyproject.toml): one name, one module
    raise ImportError(f"import softevo.worker, not {__name__}")
