# dwr_signorini on Debian trixie, whose packages carry FEniCSx 0.9.
# The package list is read from env/apt-packages.txt, the same file scripts/fenicsx uses.
FROM debian:trixie-slim

ENV DEBIAN_FRONTEND=noninteractive \
    OMPI_ALLOW_RUN_AS_ROOT=1 \
    OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1 \
    OMPI_MCA_rmaps_base_oversubscribe=1 \
    OMPI_MCA_btl=self,vader \
    PYTHONDONTWRITEBYTECODE=1

COPY env/apt-packages.txt /tmp/apt-packages.txt
RUN apt-get update \
    && sed -e 's/#.*//' -e 's/[[:space:]]//g' /tmp/apt-packages.txt | grep -v '^$' \
       | xargs apt-get install -y --no-install-recommends \
    && rm -rf /var/lib/apt/lists/* /tmp/apt-packages.txt

WORKDIR /opt/dwr_signorini
COPY . .
RUN pip3 install --no-deps --no-build-isolation --break-system-packages . \
    && python3 -c "import dwr_signorini, dolfinx; print(dolfinx.__version__)"

CMD ["mpirun", "-n", "2", "python3", "demos/bar_2d.py"]
