# omnidev: one command to set up and run the demo, one to set up and run every test.
#   make demo   - virtual environment + core + all plugins, then unwarp the fixture omni video
#   make test   - the same setup, then ruff, mypy and the whole test suite
PYTHON ?= python3
VENV   ?= .venv
BIN    := $(VENV)/bin
PLUGINS := $(wildcard plugins/*/pyproject.toml)
OUT    ?= out/demo
FIXTURE := fixtures/omni_room

.PHONY: setup demo test lint install uninstall clean

$(BIN)/python:
	$(PYTHON) -c 'import sys; assert sys.version_info >= (3, 11), "omnidev needs Python >= 3.11"'
	$(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --upgrade pip

$(VENV)/.system-deps: scripts/install-system-deps.sh | $(BIN)/python
	sh scripts/install-system-deps.sh
	touch $@

$(VENV)/.installed: $(BIN)/python $(VENV)/.system-deps pyproject.toml $(PLUGINS)
	$(BIN)/python -m pip install --quiet -e '.[test,hw,batch]' $(addprefix -e ,$(dir $(PLUGINS)))
	touch $@

setup: $(VENV)/.installed

demo: setup
	mkdir -p $(OUT)
	$(BIN)/omnidev calibrate pano-table $(FIXTURE)/landmarks.csv \
	    --mirror-center $$($(BIN)/python -c 'import json;print(",".join(map(str,json.load(open("$(FIXTURE)/truth.json"))["mirror_center_world"])))') \
	    --image $(FIXTURE)/omni_0000.png --image-center detect \
	    -o $(OUT)/camera.yml.gz --plot $(OUT)/radial_fit.png --force
	$(BIN)/omnidev unwarp $(FIXTURE)/omni.avi --camera $(OUT)/camera.yml.gz \
	    --view panorama:1280x320 -o $(OUT)/panorama.mp4 \
	    --view plane:640x480,d=1.8,w=2.4,z=-1.2:0.3,az=0 -o $(OUT)/perspective.mp4 --force
	@echo
	@echo "demo outputs in $(OUT)/:"
	@ls -l $(OUT)

lint: setup
	$(BIN)/ruff check .
	$(BIN)/ruff format --check .
	$(BIN)/mypy omnidev plugins

# Two workers (pytest-xdist): the VM test (tests/test_kernel_vm.py, one long qemu run,
# ordered first by tests/conftest.py) on one, the rest beside it on the other. Whole files
# go to a worker (loadfile), so a module-scoped fixture and the VM boot are made once.
# PYTEST_WORKERS=0 runs the suite serially. The 20 slowest tests are listed at the end
# of the run, to see where the suite's time goes.
PYTEST_WORKERS ?= 2
test: lint
	$(BIN)/python -m pytest -n $(PYTEST_WORKERS) --dist loadfile --no-loadscope-reorder --durations=20

# System files for the pointer daemon (udev rules, units, config, user): needs root.
#   sudo make install INSTALL_ARGS="--bin-dir /opt/omnidev/bin --camera 046d:0825"
install:
	sh scripts/install-system-files.sh $(INSTALL_ARGS)

uninstall:
	sh scripts/install-system-files.sh --uninstall

clean:
	rm -rf $(VENV) out build *.egg-info
