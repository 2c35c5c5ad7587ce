# softevo: one image for the API/coordinator (`softevo serve`) and the workers (`softevo worker`).
#   docker build -t softevo .
FROM python:3.11-slim

ENV PYTHONDONTWRITEBYTECODE=1 \
    PYTHONUNBUFFERED=1 \
    PIP_NO_CACHE_DIR=1 \
    NUMBA_CACHE_DIR=/var/cache/numba \
    SOFTEVO_REPORTS=/data/reports

# Install the package (not editable), then drop the sources: everything runs from
# site-packages, where the migrations are package data.
WORKDIR /src
COPY pyproject.toml README.md ./
COPY softevo ./softevo
COPY sim ./sim
COPY evolution ./evolution
COPY service ./service
COPY worker ./worker
COPY migrations ./migrations
COPY analysis ./analysis
RUN pip install ".[postgres]" && rm -rf /src

# Compile the simulator once into numba's cache, so that workers start in about a second.
WORKDIR /data
RUN useradd --create-home --uid 1000 softevo \
    && mkdir -p "$NUMBA_CACHE_DIR" /data/reports \
    && python -c "from softevo.worker.rq_worker import warm; warm()" \
    && chown -R softevo "$NUMBA_CACHE_DIR" /data
USER softevo

EXPOSE 8000
CMD ["softevo", "serve"]
