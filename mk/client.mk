# mk/client.mk -- what a controller developer links against (included by the Makefile): the
# message library as a shared object (the static one is MSG_LIB), the Java jar of the types
# that lcm-spy decodes with (afmtwin.pc and the install rules: mk/install.mk; the examples
# are built against an installed tree through pkg-config by tests/test_client.sh).

VERSION    ?= 0.1.0
MSG_SOVER  := 1
MSG_SONAME := libafmtwin_msg.so.$(MSG_SOVER)
MSG_SO     := $(BUILD)/lib/$(MSG_SONAME)
MSG_PIC    := $(patsubst $(BUILD)/gen/%.c,$(BUILD)/obj/pic/gen/%.o,$(MSG_C))
LCM_JAR    ?= /usr/share/java/lcm.jar
MSG_JAR    := $(BUILD)/java/afmtwin-lcmtypes.jar
CLIENT_ALL := $(MSG_SO) $(MSG_JAR)

$(BUILD)/obj/pic/gen/%.o: $(BUILD)/gen/%.c $(BUILD)/gen/.stamp
	@mkdir -p $(dir $@)
	$(CC) -std=c11 -O2 -g -fPIC $(LCM_CFLAGS) -I$(BUILD)/gen -c $< -o $@

$(MSG_SO): $(MSG_PIC)
	@mkdir -p $(dir $@)
	$(CC) $(LDFLAGS) -shared -Wl,-soname,$(MSG_SONAME) -Wl,--no-undefined -o $@ $^ $(LCM_LIBS)
	ln -sf $(MSG_SONAME) $(BUILD)/lib/libafmtwin_msg.so

# lcm-gen's Java classes (package afmtwin), compiled against liblcm-java's lcm.jar.
$(MSG_JAR): $(MSG_LCM)
	rm -rf $(BUILD)/java/src $(BUILD)/java/classes
	@mkdir -p $(BUILD)/java/src $(BUILD)/java/classes
	lcm-gen --java --jpath $(BUILD)/java/src $(MSG_LCM)
	javac -nowarn -Xlint:-options --release 11 -cp $(LCM_JAR) -d $(BUILD)/java/classes \
	  $$(find $(BUILD)/java/src -name '*.java')
	jar cf $@ -C $(BUILD)/java/classes .
