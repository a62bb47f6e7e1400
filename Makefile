# The README's two commands: `make demo` and `make test`. Each creates .venv and
# installs softpipe into it (editable, with the test and cluster extras) when needed.
PYTHON ?= python3
VENV   := .venv
PY     := $(VENV)/bin/python
STAMP  := $(VENV)/.installed

.PHONY: demo test test-deps lint bench bench-cold bench-peers bench-batch bench-rays bench-pt fuzz clean clean-cache

$(STAMP): pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(PY) -m pip install -q --upgrade pip
	$(PY) -m pip install -q -e '.[test,cluster]'
	touch $(STAMP)

demo: $(STAMP)
	$(PY) -m softpipe demo

# The suite on every core (pytest-xdist): one worker process per core, each taking whole test files
# (--dist loadfile: a file's module-scoped fixtures, some of them whole renders, are made on one
# worker only). Workers share numba's on-disk cache (locked: tests/numba_cache_lock.py) and
# softpipe's kernel cache; tests that read the wall clock run alone (tests/run_alone.py).
# TEST_WORKERS=1 for one worker, 0 for none (the suite in pytest's own process).
# OpenBLAS keeps one thread per worker: its threads spin-wait after each call, and two workers'
# spinning took about a tenth of the suite's CPU time (the benchmarks keep BLAS to one thread too).
TEST_WORKERS ?= auto
test: $(STAMP) test-deps lint
	OPENBLAS_NUM_THREADS=1 $(PY) -m pytest -q -n $(TEST_WORKERS) --dist loadfile

# ruff with the rule set in pyproject.toml ([tool.ruff]): the library, tests, examples, benchmarks.
lint: $(STAMP)
	$(VENV)/bin/ruff check softpipe tests benchmarks examples scripts fuzz

# What the suite needs outside Python: Debian's chromium, which tests/test_explore.py drives headless
# through Playwright (the test installs nothing: where chromium is absent it skips with the reason).
# Installed with apt-get when missing and run as root; where it cannot be, this says so and goes on.
test-deps:
	@if command -v chromium >/dev/null 2>&1; then :; \
	elif [ "$$(id -u)" != 0 ] || ! command -v apt-get >/dev/null 2>&1; then \
	  echo "chromium is missing and cannot be installed here ($$( [ "$$(id -u)" != 0 ] && echo 'not root' || echo 'no apt-get')):" \
	       "the browser test of tests/test_explore.py will skip (as root: apt-get install -y chromium)"; \
	else \
	  echo "installing chromium (apt-get) for the browser test of tests/test_explore.py ..."; \
	  log=$$(mktemp); export DEBIAN_FRONTEND=noninteractive; \
	  apt-get install -y -q chromium >$$log 2>&1 \
	    || { apt-get update -q >>$$log 2>&1; apt-get install -y -q chromium >>$$log 2>&1; } \
	    || { echo "chromium could not be installed (apt-get install -y chromium failed; the browser test will skip):"; \
	         tail -n 3 $$log; }; \
	  rm -f $$log; \
	fi

bench: $(STAMP)
	$(PY) -m benchmarks.run --scaling

# Cold start, in fresh processes (benchmarks/cold.py): `softpipe render bunny` with empty kernel
# caches, and the first draw of a user's shader (README's stripes, a lit user program).
bench-cold: $(STAMP)
	$(PY) -m benchmarks.cold

# softpipe vs Mesa's llvmpipe, alternated frame by frame (benchmarks/README.md, "Peers").
# Installs Debian's Mesa/EGL packages (apt-get, as root) and moderngl (pip) when missing;
# where it cannot, it says what is missing and skips the comparison (exit status 0).
bench-peers: $(STAMP)
	$(PY) -m benchmarks.peers --install

# softpipe batch's frames/s on LocalClusters of 1 and 2 workers: a 36-frame bunny turntable
# at 640x480, the clusters alternated, medians (docs/batch.md, "Scaling").
bench-batch: $(STAMP)
	$(PY) -m benchmarks.batch --model bunny --frames 36 --size 640x480 --workers 1,2

# BVH build times and million rays/s (primary, shadow, secondary at 1024², 1 and 2 threads) for
# the bunny and the armadillo, alternated with Intel Embree (embreex, pip-installed here when
# missing; skipped with the reason if it cannot be) (benchmarks/README.md, "Rays").
bench-rays: $(STAMP)
	$(PY) -m pip install -q embreex || echo "embreex did not install: the Embree column is skipped"
	$(PY) -m benchmarks.rays

# Path tracing samples/s: softpipe's path tracer beside Mitsuba 3 (scalar_rgb) on its Cornell box,
# the same size, spp, path length and threads, alternated (benchmarks/README.md, "Path tracing").
# Without mitsuba it says so and times softpipe alone (pip install mitsuba to compare).
bench-pt: $(STAMP)
	@$(PY) -c "import mitsuba" >/dev/null 2>&1 \
	  || echo "bench-pt: mitsuba is missing (pip install mitsuba): timing softpipe's path tracer alone, no Mitsuba column"
	$(PY) -m benchmarks.pathtrace

clean:
	rm -rf $(VENV) out build *.egg-info

# numba keeps each compiled function in __pycache__ beside its source and checks only that
# file: after editing one of softpipe's modules, a function in another module that calls it
# may still load its old compiled copy. This drops softpipe's compiled functions and its
# generated kernels (these are keyed by a hash of the sources, but take room).
clean-cache:
	find softpipe -name __pycache__ -type d -prune -exec rm -rf {} +
	rm -rf "$${SOFTPIPE_CACHE_DIR:-$${XDG_CACHE_HOME:-$$HOME/.cache}/softpipe/kernels}"
	@[ -z "$$NUMBA_CACHE_DIR" ] || echo "NUMBA_CACHE_DIR is set ($$NUMBA_CACHE_DIR): numba caches there; empty it yourself"

# Coverage-guided fuzzing of the OBJ and scene-file parsers (fuzz/README.md): atheris
# when it installs, hypothesis otherwise. SECONDS per target.
SECONDS ?= 60
fuzz: $(STAMP)
	$(PY) -m pip install -q atheris || echo "atheris did not install: fuzzing with hypothesis"
	$(PY) fuzz/run.py --seconds $(SECONDS)
