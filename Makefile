# The two commands a newcomer needs: `make test` and `make demo` (`make test-quick` while working).
# Everything runs through scripts/fenicsx, which provides dolfinx (building a cached Debian
# trixie root on hosts that lack it). `make test-current` / `make env-current` do the same with the
# current dolfinx release (Debian sid, DWR_SIGNORINI_SUITE=sid).
FENICSX := scripts/fenicsx
CURRENT_SUITE ?= sid
NP ?= 2
PYTEST := python3 -m pytest -q
DEMO_ARGS ?=

.PHONY: test test-quick test-serial test-mpi test-slow demo env lint figures test-current env-current compare-versions \
	docs docs-check docs-env

test: test-serial test-mpi

# The fast inner loop while working (about a minute, serial): the unit tests, the documentation
# (site, docstrings, every code block of README.md and docs/), an installed copy of the package,
# and one 2D solve + estimate per contact law (tests/test_quick.py). `make test` is the full run.
QUICK_TESTS := tests/test_quick.py tests/test_units.py tests/test_compat.py tests/test_stack.py \
	tests/test_quadrature.py tests/test_reconstruction.py tests/test_tensor_refine.py \
	tests/test_refinement_rules.py tests/test_bad_input.py tests/test_lifetimes.py \
	tests/test_docs.py tests/test_install.py
test-quick:
	$(FENICSX) $(PYTEST) -m "not slow" $(QUICK_TESTS)

test-serial:
	$(FENICSX) $(PYTEST) -m "not slow" tests

# The tests marked `mpi` run again on $(NP) ranks; mpi4py's runner aborts all ranks on an error.
test-mpi:
	$(FENICSX) mpirun -n $(NP) python3 -m mpi4py -m pytest -q --color=no -m "mpi and not slow" tests

test-slow:
	$(FENICSX) $(PYTEST) -m slow tests

demo:
	$(FENICSX) mpirun -n $(NP) python3 demos/bar_2d.py $(DEMO_ARGS)

env:
	$(FENICSX) python3 -c "import dolfinx, ufl, basix, petsc4py; \
	print('dolfinx', dolfinx.__version__, 'ufl', ufl.__version__, 'basix', basix.__version__, \
	'petsc4py', petsc4py.__version__)"

# The same commands with the current dolfinx release (Debian $(CURRENT_SUITE), its own cached root).
# .ci/run runs env-current first and reports a failed environment build as skipped.
test-current:
	$(MAKE) --no-print-directory test FENICSX="DWR_SIGNORINI_SUITE=$(CURRENT_SUITE) scripts/fenicsx"

env-current:
	$(MAKE) --no-print-directory env FENICSX="DWR_SIGNORINI_SUITE=$(CURRENT_SUITE) scripts/fenicsx"

# Example 5.1 (Tables 1-2, levels 0-2) and 5.2 (4 levels) on dolfinx 0.9 and the current release,
# in this invocation: J_h must agree to 1e-10, eta_p and eta to 1e-8 (relative).
COMPARE_DIR := results/compare_versions
compare-versions:
	mkdir -p $(COMPARE_DIR)
	DWR_SIGNORINI_SUITE=trixie $(FENICSX) python3 benchmarks/compare_versions.py run $(COMPARE_DIR)/trixie.json
	DWR_SIGNORINI_SUITE=$(CURRENT_SUITE) $(FENICSX) python3 benchmarks/compare_versions.py run $(COMPARE_DIR)/$(CURRENT_SUITE).json
	$(FENICSX) python3 benchmarks/compare_versions.py compare $(COMPARE_DIR)/trixie.json $(COMPARE_DIR)/$(CURRENT_SUITE).json

# The documentation site, from docs/ (Sphinx, MyST, furo: Debian packages of env/apt-packages.txt),
# in the environment of the tests (autodoc imports dwr_signorini), offline. HTML in docs/_build/html.
SPHINX := python3 -m sphinx -q -j 1
docs:
	$(FENICSX) $(SPHINX) -b html docs docs/_build/html

lint:
	@command -v ruff >/dev/null 2>&1 || python3 -m pip install --quiet ruff
	ruff check .

# The site's pictures (docs/img): run the demos at their defaults (the finite-strain one with its
# reference, a few minutes) and copy the PNGs to docs/img.
figures:
	$(FENICSX) mpirun -n $(NP) python3 demos/bar_2d.py
	$(FENICSX) mpirun -n $(NP) python3 demos/analytic_2d.py
	$(FENICSX) mpirun -n $(NP) python3 demos/obstacle_3d.py
	$(FENICSX) mpirun -n $(NP) python3 demos/hertz.py --dim 2
	$(FENICSX) mpirun -n $(NP) python3 demos/finite_strain.py --reference 3
	mkdir -p docs/img
	cp results/bar_2d/convergence_cells.png docs/img/bar_convergence_cells.png
	cp results/bar_2d/convergence_time.png docs/img/bar_convergence_time.png
	cp results/bar_2d/mesh_level05.png docs/img/bar_mesh_level05.png
	cp results/bar_2d/solution.png docs/img/bar_solution.png
	cp results/analytic_2d/effectivity.png docs/img/analytic_effectivity.png
	cp results/analytic_2d/sweep.png docs/img/analytic_sweep.png
	cp results/obstacle_3d/solution.png docs/img/obstacle_solution.png
	cp results/hertz_2d/pressure_profile.png docs/img/hertz_pressure_profile.png
	cp results/hertz_2d/errors_dofs.png docs/img/hertz_errors_dofs.png
	for f in deformed_meshes contact_pressure force_displacement; do \
		cp results/finite_strain/$$f.png docs/img/finite_strain_$$f.png; done

# Optional peer codes for benchmarks/peers.py (env/peer-packages.txt: GetFEM), never a dependency
# of the package. `make peer-env` runs apt-get through $(FENICSX), so the packages go where every
# other command runs: into the cached Debian root (inside it, with the same unshare + chroot), or
# onto a Debian host of the suite. The root's package list, hence its hash key, is unchanged: the
# environment of `make test` and CI is still built from env/apt-packages.txt alone, and a root
# rebuilt from a changed list lacks the peer until `make peer-env` runs again. Only new packages
# are added: if apt would upgrade or remove an installed package, nothing is installed; afterwards
# the BLAS/LAPACK alternatives must be the ones they were. Ends with `peers.py --check`.
# ENV_ADD_SH NAME LIST [CHECK...]: add the packages of LIST so, then run CHECK (docs-env uses it too).
PEER_PACKAGES := env/peer-packages.txt
define ENV_ADD_SH
pkgs=$$(sed -e 's/#.*//' "$$1" | tr -s '[:space:]' ' ')
command -v apt-get >/dev/null 2>&1 || { echo "$$0: no apt-get in this environment: install$$pkgs by other means" >&2; exit 2; }
[ "$$(id -u)" = 0 ] || { echo "$$0: apt-get install needs root" >&2; exit 2; }
missing=""
for p in $$pkgs; do
    dpkg-query -W -f='$${Status}' "$$p" 2>/dev/null | grep -q ' installed$$' || missing="$$missing $$p"
done
if [ -z "$$missing" ]; then
    echo "$$0: already installed:$$pkgs"
else
    blas() { for a in /etc/alternatives/libblas* /etc/alternatives/liblapack*; do
        [ -e "$$a" ] && echo "$$a -> $$(readlink -f "$$a")"; done; true; }
    before=$$(blas)
    echo "$$0: apt-get install$$missing"
    apt-get update -qq
    changes=$$(apt-get install -s --no-install-recommends $$missing | grep -E '^(Inst [^ ]+ \[|Remv )' || true)
    if [ -n "$$changes" ]; then
        echo "$$0: not installing: apt would change packages already in the environment:" >&2
        echo "$$changes" >&2; exit 1
    fi
    DEBIAN_FRONTEND=noninteractive apt-get install -y -qq --no-install-recommends $$missing >/dev/null
    apt-get clean
    if [ -f /.dwr-signorini-complete ]; then rm -f /var/lib/apt/lists/*_Packages; fi
    [ "$$(blas)" = "$$before" ] || { echo "$$0: the BLAS/LAPACK alternatives changed:" >&2; blas >&2; exit 1; }
fi
shift
[ $$# -eq 0 ] || "$$@"
endef
export ENV_ADD_SH

.PHONY: peer-env
peer-env:
	$(FENICSX) sh -ec "$$ENV_ADD_SH" peer-env $(PEER_PACKAGES) python3 benchmarks/peers.py --check

# Optional PyPI peers for benchmarks/peer_felupe.py (env/peer-pypi.txt: felupe), never a
# dependency of the package: pip installs them with --no-deps into benchmarks/.peers (ignored by
# git), which the benchmark puts on sys.path; numpy and scipy come from the environment. The
# wheels are fetched by the host's pip (a cached Debian root may not trust the host's
# certificates) and installed by the environment's own pip from them, offline. Ends with
# `peer_felupe.py --check`.
PEER_PYPI := env/peer-pypi.txt
PEER_PYPI_DIR := benchmarks/.peers
.PHONY: peer-felupe
peer-felupe:
	python3 -m pip download --quiet --no-deps --only-binary=:all: -d $(PEER_PYPI_DIR)/wheels -r $(PEER_PYPI)
	$(FENICSX) python3 -m pip install --quiet --no-index --no-deps --upgrade \
		--find-links $(PEER_PYPI_DIR)/wheels --target $(PEER_PYPI_DIR) -r $(PEER_PYPI)
	$(FENICSX) python3 benchmarks/peer_felupe.py --check

# `make docs-check`: the site built anew with warnings as errors (-W, every page read again), every
# internal link, anchor and image checked (docs/check_site.py), and the landing page and a demo page
# rendered by headless Chromium to docs/screenshots/*.png. Chromium is not in the environment's
# package list (it would weigh on every root and image): `make docs-env` adds the packages of
# env/docs-packages.txt to the environment as `make peer-env` does, once.
DOCS_PACKAGES := env/docs-packages.txt
docs-env:
	$(FENICSX) sh -ec "$$ENV_ADD_SH" docs-env $(DOCS_PACKAGES) chromium --version

docs-check: docs-env
	$(FENICSX) $(SPHINX) -E -W --keep-going -b html docs docs/_build/html
	$(FENICSX) python3 docs/check_site.py docs/_build/html --screenshots docs/screenshots
