# mk/cross.mk -- `make cross-arm64` (README "Portable builds"): the whole tree (engine,
# transports, daemon, tools, every unit test) built for arm64 by the default (portable)
# build with Debian's cross compiler, and every unit test and `afmtwin modes` run under
# qemu-aarch64 (qemu-user). Included by the Makefile; not in make test (downloads, and
# minutes of emulation: README).
#
# Headers: the host's -dev packages (SUNDIALS, LAPACKE, libconfig, cJSON, FFTW, systemd,
# LCM: architecture independent) via -idirafter /usr/include. Libraries: the arm64 runtime
# packages, fetched with `apt-get download` (dpkg's arm64 architecture added, nothing
# installed: liblcm1:arm64 is not co-installable with the host's liblcm-dev) and unpacked
# into $(CROSS_ROOT); the linker finds them through lib*.so links in $(CROSS_LINK), qemu
# through QEMU_LD_PREFIX (the cross toolchain's libc) and LD_LIBRARY_PATH.
CROSS_PKGS  := gcc-aarch64-linux-gnu libc6-dev-arm64-cross qemu-user
CROSS_CC    ?= aarch64-linux-gnu-gcc
CROSS_AR    ?= aarch64-linux-gnu-ar
CROSS_BUILD ?= $(BUILD)/arm64
CROSS_LIBC  ?= /usr/aarch64-linux-gnu
CROSS_ROOT  := $(CROSS_BUILD)/sysroot
CROSS_LINK  := $(CROSS_BUILD)/sysroot-link
CROSS_LIBDIR := $(CROSS_ROOT)/usr/lib/aarch64-linux-gnu
# The arm64 runtime libraries and what they need beyond libc.
CROSS_RUNTIME := liblcm1 libglib2.0-0 libsundials-cvodes6 libsundials-arkode5 \
  libsundials-nvecserial6 liblapacke liblapack3 libblas3 libtmglib3 libgfortran5 libconfig9 \
  libcjson1 libfftw3-double3 libgomp1 libsystemd0 libcap2 libgcrypt20 liblz4-1 liblzma5 \
  libzstd1 libgpg-error0 libffi8 libpcre2-8-0 libmount1 libselinux1 libblkid1 zlib1g
# -l name -> the runtime file it links against (relative to $(CROSS_LIBDIR))
CROSS_SONAMES := sundials_cvodes:libsundials_cvodes.so.6 sundials_arkode:libsundials_arkode.so.5 \
  sundials_nvecserial:libsundials_nvecserial.so.6 lapacke:liblapacke.so.3 \
  lapack:lapack/liblapack.so.3 blas:blas/libblas.so.3 config:libconfig.so.9 cjson:libcjson.so.1 \
  fftw3:libfftw3.so.3 systemd:libsystemd.so.0 lcm:liblcm.so.1 glib-2.0:libglib-2.0.so.0 \
  gthread-2.0:libgthread-2.0.so.0
CROSS_RPATH := $(CROSS_LIBDIR):$(CROSS_ROOT)/lib/aarch64-linux-gnu:$(CROSS_LIBDIR)/blas:$(CROSS_LIBDIR)/lapack
CROSS_MAKE  := $(MAKE) --no-print-directory BUILD=$(CROSS_BUILD) CC=$(CROSS_CC) AR=$(CROSS_AR) \
  AFMTWIN_MARCH=portable AFMTWIN_MPI=0 EXTRA_CFLAGS="-idirafter /usr/include" \
  LDFLAGS="-L$(abspath $(CROSS_LINK)) -Wl,-rpath-link,$(abspath $(CROSS_RPATH))"
# The unit tests run (default all; CROSS_TESTS="test_rt test_cmd" for some: under qemu-user
# test_continue and test_thesis_sweeps take ~20-40x their native 30-45 s)
CROSS_TESTS ?= $(notdir $(TEST_BIN))
CROSS_RUN   := QEMU_LD_PREFIX=$(CROSS_LIBC) QEMU_SET_ENV=LD_LIBRARY_PATH=$(abspath $(CROSS_RPATH)) \
  qemu-aarch64

cross-deps: deps
	$(call apt_install,$(CROSS_PKGS))
	@dpkg --print-foreign-architectures | grep -qx arm64 || { \
	  SUDO=""; [ "$$(id -u)" -eq 0 ] || SUDO=sudo; \
	  echo "adding dpkg architecture arm64 (for apt-get download of arm64 libraries)"; \
	  $$SUDO dpkg --add-architecture arm64 && $$SUDO apt-get update -qq; }

$(CROSS_ROOT)/.stamp:
	@rm -rf $(CROSS_ROOT) $(CROSS_LINK) && mkdir -p $(CROSS_ROOT)/debs $(CROSS_LINK)
	cd $(CROSS_ROOT)/debs && apt-get download -q $(addsuffix :arm64,$(CROSS_RUNTIME)) 2>&1 | \
	  grep -v '^W: Download is performed unsandboxed' || true
	for d in $(CROSS_ROOT)/debs/*.deb; do dpkg-deb -x $$d $(CROSS_ROOT); done
	for p in $(CROSS_SONAMES); do \
	  ln -sf $(abspath $(CROSS_LIBDIR))/$${p#*:} $(CROSS_LINK)/lib$${p%%:*}.so; done
	@for p in $(CROSS_SONAMES); do [ -e $(CROSS_LINK)/lib$${p%%:*}.so ] || \
	  { echo "cross-arm64: $(CROSS_LIBDIR)/$${p#*:} missing"; exit 1; }; done
	@touch $@

# Prints each test's last line and a total "N passed, N failed"; fails if any failed.
cross-arm64: cross-deps $(CROSS_ROOT)/.stamp
	$(CROSS_MAKE) core
	@p=0; f=0; \
	m=$$($(CROSS_RUN) $(CROSS_BUILD)/bin/afmtwin modes --config config/default.conf 2>&1 | \
	  awk '$$1 == "1" {print $$NF}'); \
	if [ -n "$$m" ]; then echo "arm64 (qemu-aarch64) afmtwin modes: f1 $$m Hz"; p=$$((p + 1)); \
	else echo "arm64 (qemu-aarch64) afmtwin modes: FAILED"; f=$$((f + 1)); fi; \
	for t in $(CROSS_TESTS); do \
	  last=$$($(CROSS_RUN) $(CROSS_BUILD)/tests/$$t 2>&1 | tail -n 1); \
	  echo "arm64 (qemu-aarch64) $$t: $$last"; \
	  set -- $$(echo "$$last" | sed -n 's/^\([0-9]*\) passed, \([0-9]*\) failed.*/\1 \2/p'); \
	  if [ $$# -eq 2 ]; then p=$$((p + $$1)); f=$$((f + $$2)); else f=$$((f + 1)); fi; \
	done; echo "$$p passed, $$f failed"; [ $$f -eq 0 ]
