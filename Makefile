# ctdrill: make demo | make test | make bench | make fuzz
SHELL := /bin/bash
PYTHON ?= python3
VENV := .venv
PY := $(VENV)/bin/python
STAMP := $(VENV)/.installed-dev
STAMP_RUN := $(VENV)/.installed
# libegl1 + libegl-mesa0 + libgl1-mesa-dri: the 3D view's render thread and the report draw in an
# off-screen EGL window (Mesa's llvmpipe: no display, no GPU needed)
SYSTEM_PKGS := xvfb xauth libegl1 libegl-mesa0 libgl1-mesa-dri libgl1 libxkbcommon-x11-0 libxcb-cursor0 libxcb-icccm4 \
	libxcb-keysyms1 libxcb-shape0 libxcb-xinerama0 libxcb-randr0 libxcb-render-util0 \
	libxcb-image0 libxrender1 libfontconfig1 libdbus-1-3 dicom3tools libportaudio2 \
	gcc libc6-dev
DEMO_OUT ?= demo-out

.PHONY: test-blas bench-smoke demo test bench fuzz lint typecheck sysdeps venv venv-dev wheel-check clean warmup firmware firmware-cycles

$(VENV)/bin/python:
	$(PYTHON) -m venv $(VENV)
	$(PY) -m pip install --quiet --upgrade pip

$(STAMP_RUN): pyproject.toml | $(VENV)/bin/python
	$(PY) -m pip install -q -q -e .
	touch $@

$(STAMP): pyproject.toml | $(VENV)/bin/python
	$(PY) -m pip install -q -q -e '.[dev]'
	touch $@ $(STAMP_RUN)

venv: $(STAMP_RUN)
venv-dev: $(STAMP)

## System packages the tests need (Xvfb and the Qt/VTK X11 libraries; gcc builds the firmware core
## for `--core c` and its equality tests); installed when root.
sysdeps:
	@missing=$$(for p in $(SYSTEM_PKGS); do dpkg -s $$p >/dev/null 2>&1 || echo $$p; done); \
	if [ -n "$$missing" ]; then \
	  if [ "$$(id -u)" = 0 ]; then \
	    echo "installing system packages: $$missing"; \
	    DEBIAN_FRONTEND=noninteractive apt-get update -qq && \
	    DEBIAN_FRONTEND=noninteractive apt-get install -y -qq --no-install-recommends $$missing >/dev/null; \
	  else \
	    echo "error: missing system packages: $$missing (install them with apt-get as root)"; exit 2; \
	  fi; \
	fi

demo: $(STAMP_RUN)
	$(VENV)/bin/ctdrill demo --out $(DEMO_OUT)

lint: $(STAMP)
	$(VENV)/bin/ruff format --check .
	$(VENV)/bin/ruff check .

typecheck: $(STAMP)
	bash scripts/typecheck.sh

## The fit's numerics on another BLAS code path (CI hosts differ: AMD, Intel): the model's tests
## again with OpenBLAS's Haswell kernels.
test-blas: $(STAMP)
	OPENBLAS_CORETYPE=Haswell $(PY) -m pytest -q -p no:cacheprovider tests/model tests/app/test_calibrate.py

## Compile the trajectory-search kernels into numba's disk cache (once per install; CI runs it
## before the tests, with NUMBA_CACHE_DIR on a cached folder when the tree is read-only).
warmup: $(STAMP_RUN)
	$(PY) -m ctdrill.app.search.warmup

## ruff, the warm-up, then pytest on 2 workers (pytest-xdist, one a core on CI; the window
## tests run one after another in one worker, tests/conftest.py) with mypy (single-threaded,
## ~50 s of CPU from a cold cache) beside them; its report is printed after the tests and
## either failing fails the target.
PYTEST_WORKERS ?= 2
test: sysdeps $(STAMP) lint warmup
	bash scripts/typecheck.sh > $(VENV)/typecheck.log 2>&1 & tc=$$!; \
	QT_QPA_PLATFORM=xcb xvfb-run -a -s "-screen 0 1600x1000x24" $(PY) -m pytest -q -p no:cacheprovider -m "not bench_smoke" -n $(PYTEST_WORKERS) --dist loadscope; \
	rc=$$?; wait $$tc; trc=$$?; echo "mypy (bash scripts/typecheck.sh):"; cat $(VENV)/typecheck.log; \
	[ $$rc -eq 0 ] && [ $$trc -eq 0 ]

## Every benchmark module at toy sizes, its report written aside (about a minute; CI runs it)
bench-smoke: sysdeps $(STAMP) warmup
	QT_QPA_PLATFORM=xcb xvfb-run -a -s "-screen 0 1600x1000x24" $(PY) -m pytest -q -p no:cacheprovider -m bench_smoke

bench: sysdeps $(STAMP) warmup
	MALLOC_TRIM_THRESHOLD_=17179869184 MALLOC_MMAP_THRESHOLD_=33554432 xvfb-run -a -s "-screen 0 1600x1000x24" $(PY) -m bench

fuzz: $(STAMP)
	CTDRILL_FUZZ_EXAMPLES=20000 $(PY) -m pytest -q -p no:cacheprovider tests -m fuzz

## The firmware for a Cortex-M4F (firmware/README.md): Debian's arm-none-eabi toolchain is
## installed as root for this target only; the image and its size in build/firmware/.
ARM_PKGS := gcc-arm-none-eabi libnewlib-arm-none-eabi binutils-arm-none-eabi
ARM_CC := arm-none-eabi-gcc -mcpu=cortex-m4 -mthumb -mfpu=fpv4-sp-d16 -mfloat-abi=hard -std=c99 \
	-O2 -ffp-contract=off -ffunction-sections -fdata-sections -Wall -Wextra -Werror -DFW_REAL_FLOAT \
	--specs=nano.specs --specs=nosys.specs -nostartfiles -Wl,--gc-sections -T firmware/board/m4f.ld
FW_SOURCES := firmware/fw_frame.c firmware/fw_render.c firmware/fw_device.c \
	firmware/board/m4f_board.c firmware/board/m4f_start.c
firmware:
	@$(MAKE) --no-print-directory sysdeps SYSTEM_PKGS="$(ARM_PKGS)"
	mkdir -p build/firmware
	$(ARM_CC) -o build/firmware/ctdrill-m4f.elf $(FW_SOURCES) -lm
	arm-none-eabi-objcopy -O binary build/firmware/ctdrill-m4f.elf build/firmware/ctdrill-m4f.bin
	arm-none-eabi-size build/firmware/ctdrill-m4f.elf

## Instructions per tick counted by QEMU (-icount) on a Cortex-M4F, priced in cycles
## (scripts/firmware_cycles.py) against the 100 us budget at 168 MHz.
firmware-cycles: firmware $(STAMP_RUN)
	@$(MAKE) --no-print-directory sysdeps SYSTEM_PKGS="qemu-system-arm"
	$(ARM_CC) -DFW_NO_MAIN -o build/firmware/ctdrill-m4f-cycles.elf $(FW_SOURCES) \
		firmware/board/m4f_cycles.c -lm
	timeout 300 qemu-system-arm -M netduinoplus2 -nographic -semihosting -icount shift=0 \
		-kernel build/firmware/ctdrill-m4f-cycles.elf > build/firmware/cycles.txt 2>&1
	$(PY) scripts/firmware_cycles.py build/firmware/ctdrill-m4f-cycles.elf build/firmware/cycles.txt

## Build the wheel, install it into a scratch venv and run the demo from outside the checkout.
wheel-check: | $(VENV)/bin/python
	bash scripts/wheel_check.sh $(PYTHON)

clean:
	rm -rf $(VENV) build *.egg-info $(DEMO_OUT)
