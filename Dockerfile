# dwr_signorini on Debian: trixie (the default) carries FEniCSx 0.9, sid the current release.
#
#   docker build -t dwr-signorini .                                # dolfinx 0.9 (Debian trixie)
#   docker build --build-arg SUITE=sid -t dwr-signorini:current .  # current dolfinx (Debian sid)
#
# The package list is env/packages SUITE (env/apt-packages.txt, amended by
# env/apt-packages-SUITE.txt if present), the same list scripts/fenicsx installs.
ARG SUITE=trixie
FROM debian:${SUITE}-slim
ARG SUITE

ENV DEBIAN_FRONTEND=noninteractive \
    OMPI_ALLOW_RUN_AS_ROOT=1 \
    OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1 \
    OMPI_MCA_rmaps_base_oversubscribe=1 \
    OMPI_MCA_btl=self,vader \
    PYTHONDONTWRITEBYTECODE=1

COPY env/ /tmp/env/
# sid: a mirror's index may carry an expired Valid-Until date, which apt refuses by default.
RUN if [ "$SUITE" = sid ]; then \
        echo 'Acquire::Check-Valid-Until "false";' > /etc/apt/apt.conf.d/99no-check-valid-until; \
    fi \
    && apt-get update \
    && sh /tmp/env/packages "$SUITE" | xargs apt-get install -y --no-install-recommends \
    && rm -rf /var/lib/apt/lists/* /tmp/env

WORKDIR /opt/dwr_signorini
COPY . .
RUN pip3 install --no-deps --no-build-isolation --break-system-packages . \
    && python3 -c "import dwr_signorini, dolfinx; print(dolfinx.__version__)"

CMD ["mpirun", "-n", "2", "python3", "demos/bar_2d.py"]
