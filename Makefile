# afmtwin build: engine library (daemon/engine) linked by the CLI (tools/) and the tests.
# Out-of-tree into build/. `make run` and `make test` install missing Debian packages first.

PREFIX  ?= /usr/local
DESTDIR ?=
BUILD   ?= build
CC      ?= cc

DEB_PKGS := build-essential pkg-config liblcm-dev liblcm-bin libglib2.0-dev libsundials-dev \
            liblapacke-dev libconfig-dev libsystemd-dev libcjson-dev can-utils gnuplot-nox \
            libfftw3-dev

CSTD     := -std=c11 -D_POSIX_C_SOURCE=200809L
WARN     := -Wall -Wextra -Werror -Wshadow -Wstrict-prototypes -Wmissing-prototypes
OPT      ?= -O2 -march=x86-64-v3 -g
CFLAGS   += $(CSTD) $(WARN) $(OPT) -Idaemon/engine
LDLIBS   += -lsundials_cvode -lsundials_arkode -lsundials_nvecserial \
            -llapacke -llapack -lblas -lconfig -lcjson -lm

ENGINE_SRC := $(wildcard daemon/engine/*.c)
ENGINE_OBJ := $(patsubst %.c,$(BUILD)/obj/%.o,$(ENGINE_SRC))
ENGINE_LIB := $(BUILD)/lib/libafmtwin.a
TOOL_SRC   := $(wildcard tools/*.c)
TOOL_OBJ   := $(patsubst %.c,$(BUILD)/obj/%.o,$(TOOL_SRC))
TEST_SRC   := $(wildcard tests/test_*.c)
TEST_BIN   := $(patsubst tests/%.c,$(BUILD)/tests/%,$(TEST_SRC))
TEST_COMMON := $(BUILD)/obj/tests/check.o

.PHONY: all deps run test validate bench install clean format format-check

all: $(BUILD)/bin/afmtwin $(TEST_BIN)

# Install what is missing (apt-get as root, sudo otherwise). Quiet when all is present.
deps:
	@missing=""; for p in $(DEB_PKGS); do \
	  dpkg -s $$p >/dev/null 2>&1 || missing="$$missing $$p"; done; \
	if [ -n "$$missing" ]; then \
	  echo "installing:$$missing"; \
	  SUDO=""; [ "$$(id -u)" -eq 0 ] || SUDO=sudo; \
	  $$SUDO apt-get update -qq && \
	  DEBIAN_FRONTEND=noninteractive $$SUDO apt-get install -y -qq --no-install-recommends $$missing; \
	fi

$(BUILD)/obj/%.o: %.c
	@mkdir -p $(dir $@)
	$(CC) $(CFLAGS) -MMD -MP -c $< -o $@

$(ENGINE_LIB): $(ENGINE_OBJ)
	@mkdir -p $(dir $@)
	$(AR) rcs $@ $^

$(BUILD)/bin/afmtwin: $(TOOL_OBJ) $(ENGINE_LIB)
	@mkdir -p $(dir $@)
	$(CC) $(CFLAGS) -o $@ $(TOOL_OBJ) $(ENGINE_LIB) $(LDLIBS)

$(BUILD)/tests/%: $(BUILD)/obj/tests/%.o $(TEST_COMMON) $(ENGINE_LIB)
	@mkdir -p $(dir $@)
	$(CC) $(CFLAGS) -o $@ $^ $(LDLIBS)

run: deps
	$(MAKE) $(BUILD)/bin/afmtwin
	$(BUILD)/bin/afmtwin modes --config config/default.conf

test: deps
	$(MAKE) all
	@bash tests/run.sh $(BUILD)

validate: deps
	$(MAKE) all
	@AFMTWIN_VALIDATE=full bash tests/run.sh $(BUILD)
	@bash tools/validation-doc.sh $(BUILD) > docs/validation.md

bench: deps
	$(MAKE) $(BUILD)/bin/afmtwin
	$(BUILD)/bin/afmtwin bench

install: $(BUILD)/bin/afmtwin
	install -d $(DESTDIR)$(PREFIX)/bin $(DESTDIR)$(PREFIX)/share/afmtwin/config
	install -m 755 $(BUILD)/bin/afmtwin $(DESTDIR)$(PREFIX)/bin/
	install -m 644 config/*.conf $(DESTDIR)$(PREFIX)/share/afmtwin/config/

clean:
	rm -rf $(BUILD)

format:
	clang-format -i daemon/engine/*.[ch] tools/*.[ch] tests/*.[ch]

format-check:
	clang-format --dry-run --Werror daemon/engine/*.[ch] tools/*.[ch] tests/*.[ch]

-include $(shell find $(BUILD)/obj -name '*.d' 2>/dev/null)
