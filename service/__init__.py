if __name__ != "softevo.service":  # installed as softevo.service (pyproject.toml): one name, one module
    raise ImportError(f"import softevo.service, not {__name__}")
