# mk/cross.mk -- `make cross-arm64` (README "Portable builds"): the engine built for arm64
# with Debian's cross compiler (gcc-aarch64-linux-gnu, the portable flavour: -march=armv8-a,
# no x86 code), and the unit tests that need nothing but the engine and libc run under
# qemu-aarch64 (qemu-user) with the cross toolchain's arm64 libc. Included by the Makefile.
# The -dev headers of the host's packages (SUNDIALS, LAPACKE, libconfig, FFTW: architecture
# independent) serve to compile the engine; the tests run here link only the engine's own
# objects, so no arm64 copy of those libraries is needed. Not in make test: the toolchain
# install and ~1-2 min of compile and emulation (README).
CROSS_PKGS  := gcc-aarch64-linux-gnu libc6-dev-arm64-cross qemu-user
CROSS_CC    ?= aarch64-linux-gnu-gcc
CROSS_AR    ?= aarch64-linux-gnu-ar
CROSS_BUILD ?= $(BUILD)/arm64
CROSS_LIBC  ?= /usr/aarch64-linux-gnu
CROSS_TESTS := test_decim test_cycle test_force test_spsc
CROSS_FLAGS := $(CSTD) $(WARN) -O2 -g -march=armv8-a -idirafter /usr/include
CROSS_OBJ   := $(patsubst %.c,$(CROSS_BUILD)/obj/%.o,$(ENGINE_SRC))

cross-deps: deps
	$(call apt_install,$(CROSS_PKGS))

$(CROSS_BUILD)/obj/%.o: %.c
	@mkdir -p $(dir $@)
	$(CROSS_CC) $(CROSS_FLAGS) $(ENGINE_INC) -Itests -MMD -MP -c $< -o $@

$(CROSS_BUILD)/lib/libafmtwin.a: $(CROSS_OBJ)
	@mkdir -p $(dir $@)
	rm -f $@ && $(CROSS_AR) rcs $@ $^

$(CROSS_BUILD)/tests/%: $(CROSS_BUILD)/obj/tests/%.o $(CROSS_BUILD)/obj/tests/check.o \
                        $(CROSS_BUILD)/lib/libafmtwin.a
	@mkdir -p $(dir $@)
	$(CROSS_CC) $(CROSS_FLAGS) -o $@ $^ -lpthread -lm

# Prints each test's last line and a total "N passed, N failed"; fails if any failed.
cross-arm64: cross-deps
	$(MAKE) --no-print-directory $(CROSS_BUILD)/lib/libafmtwin.a \
	  $(addprefix $(CROSS_BUILD)/tests/,$(CROSS_TESTS))
	@p=0; f=0; for t in $(CROSS_TESTS); do \
	  last=$$(cd $(CROSS_BUILD)/tests && qemu-aarch64 -L $(CROSS_LIBC) ./$$t 2>&1 | tail -n 1); \
	  echo "arm64 (qemu-aarch64) $$t: $$last"; \
	  set -- $$(echo "$$last" | sed -n 's/^\([0-9]*\) passed, \([0-9]*\) failed.*/\1 \2/p'); \
	  if [ $$# -eq 2 ]; then p=$$((p + $$1)); f=$$((f + $$2)); else f=$$((f + 1)); fi; \
	done; echo "$$p passed, $$f failed"; [ $$f -eq 0 ]

-include $(CROSS_OBJ:.o=.d) $(CROSS_BUILD)/obj/tests/check.d \
         $(addprefix $(CROSS_BUILD)/obj/tests/,$(addsuffix .d,$(CROSS_TESTS)))
.PRECIOUS: $(CROSS_BUILD)/obj/tests/%.o
