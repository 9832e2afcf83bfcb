# mk/install.mk -- `make install` (PREFIX, DESTDIR, LIBDIR, SYSCONFDIR), the man pages and
# `make deb` (included by the Makefile).
#
# Installed under PREFIX: bin/afmtwin, bin/afmtwind; the client side (include/afmtwin/ with
# the generated headers and afmtwin_lcm_layout.h, LIBDIR/libafmtwin_msg.{a,so}, LIBDIR/
# pkgconfig/afmtwin.pc, share/afmtwin/lcmtypes/*.lcm, share/java/afmtwin-lcmtypes.jar);
# share/afmtwin/config/ (the model files), share/doc/afmtwin/ (README, docs, examples),
# share/man/man{1,8}; SYSCONFDIR/afmtwin/afmtwind.conf (the service's config: /etc for
# PREFIX=/usr, else PREFIX/etc; an existing one is kept) and the systemd unit.

LIBDIR          ?= $(PREFIX)/lib
SYSCONFDIR      ?= $(if $(filter /usr,$(PREFIX)),/etc,$(PREFIX)/etc)
MANDIR          ?= $(PREFIX)/share/man
DOCDIR          ?= $(PREFIX)/share/doc/afmtwin
SYSTEMD_UNIT_DIR ?= $(PREFIX)/lib/systemd/system
SERVICE_CONF    := $(SYSCONFDIR)/afmtwin/afmtwind.conf
MAN_PAGES       := $(BUILD)/man/afmtwin.1 $(BUILD)/man/afmtwind.8

# `afmtwin send` checks against the service's config when given none (the object is not
# rebuilt when only PREFIX changes: build and install with the same PREFIX).
$(BUILD)/obj/tools/cmd_send.o: CFLAGS += -DAFMT_SERVICE_CONF='"$(SERVICE_CONF)"'

# help2man runs the binaries' --help and --version; man/*.h2m add the sections --help has
# no room for (files, LCM layout, signals, exit status).
$(BUILD)/man/afmtwind.8: $(BUILD)/bin/afmtwind man/afmtwind.h2m
	@mkdir -p $(dir $@)
	help2man --no-info --section 8 --name "real-time AFM cantilever digital twin daemon" \
	  --include man/afmtwind.h2m --output $@ $(BUILD)/bin/afmtwind
$(BUILD)/man/afmtwin.1: $(BUILD)/bin/afmtwin man/afmtwin.h2m
	@mkdir -p $(dir $@)
	help2man --no-info --section 1 --name "tools of the afmtwin AFM cantilever twin" \
	  --include man/afmtwin.h2m --output $@ $(BUILD)/bin/afmtwin
man: $(MAN_PAGES)

# What install installs (no tests): what debian/rules builds.
dist: $(BUILD)/bin/afmtwin $(BUILD)/bin/afmtwind $(MSG_LIB) $(CLIENT_ALL) $(MAN_PAGES)

install: dist
	install -d $(DESTDIR)$(PREFIX)/bin $(DESTDIR)$(PREFIX)/include/afmtwin \
	  $(DESTDIR)$(LIBDIR)/pkgconfig $(DESTDIR)$(PREFIX)/share/afmtwin/config \
	  $(DESTDIR)$(PREFIX)/share/afmtwin/lcmtypes $(DESTDIR)$(PREFIX)/share/java \
	  $(DESTDIR)$(DOCDIR)/docs $(DESTDIR)$(DOCDIR)/examples \
	  $(DESTDIR)$(MANDIR)/man1 $(DESTDIR)$(MANDIR)/man8 \
	  $(DESTDIR)$(SYSCONFDIR)/afmtwin $(DESTDIR)$(SYSTEMD_UNIT_DIR)
	install -m 755 $(BUILD)/bin/afmtwin $(BUILD)/bin/afmtwind $(DESTDIR)$(PREFIX)/bin/
	install -m 644 $(BUILD)/gen/afmtwin_*.h msgtypes/afmtwin_lcm_layout.h \
	  $(DESTDIR)$(PREFIX)/include/afmtwin/
	install -m 644 $(MSG_LIB) $(DESTDIR)$(LIBDIR)/
	install -m 644 $(MSG_SO) $(DESTDIR)$(LIBDIR)/
	ln -sf $(MSG_SONAME) $(DESTDIR)$(LIBDIR)/libafmtwin_msg.so
	sed -e 's|@PREFIX@|$(PREFIX)|' -e 's|@LIBDIR@|$(LIBDIR)|' -e 's|@VERSION@|$(VERSION)|' \
	  msgtypes/afmtwin.pc.in > $(DESTDIR)$(LIBDIR)/pkgconfig/afmtwin.pc
	install -m 644 $(MSG_LCM) $(DESTDIR)$(PREFIX)/share/afmtwin/lcmtypes/
	install -m 644 $(MSG_JAR) $(DESTDIR)$(PREFIX)/share/java/
	install -m 644 config/*.conf config/README.md $(DESTDIR)$(PREFIX)/share/afmtwin/config/
	install -m 644 README.md $(DESTDIR)$(DOCDIR)/
	install -m 644 docs/*.md $(DESTDIR)$(DOCDIR)/docs/
	install -m 644 examples/*.c examples/Makefile examples/README.md $(DESTDIR)$(DOCDIR)/examples/
	install -m 644 $(BUILD)/man/afmtwin.1 $(DESTDIR)$(MANDIR)/man1/
	install -m 644 $(BUILD)/man/afmtwind.8 $(DESTDIR)$(MANDIR)/man8/
	[ -e $(DESTDIR)$(SERVICE_CONF) ] || install -m 644 config/default.conf $(DESTDIR)$(SERVICE_CONF)
	sed -e 's|/usr/local/etc/|$(SYSCONFDIR)/|g' -e 's|/usr/local/|$(PREFIX)/|g' \
	  systemd/afmtwind.service > $(DESTDIR)$(SYSTEMD_UNIT_DIR)/afmtwind.service
	chmod 644 $(DESTDIR)$(SYSTEMD_UNIT_DIR)/afmtwind.service
	@echo "installed $(SYSTEMD_UNIT_DIR)/afmtwind.service (config $(SERVICE_CONF);" \
	  "systemctl daemon-reload; systemctl start afmtwind)"

# The Debian packages (debian/): built out of a copy of the tree, so that this worktree's
# build/ and debian/ stay as they are; then unpacked into a scratch root and run there.
DEB_OUT ?= $(BUILD)/deb
deb: deps
	@bash tests/deb.sh $(DEB_OUT)
