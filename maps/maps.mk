# Maps: drawn sources (maps/src/<name>.png) -> image_to_bw -> png_to_ros_map -> maps/<name>.pgm +
# maps/<name>.yaml, at 0.05 m per pixel. Included by the root Makefile, which defines PYTHON,
# ROOT and VENV_STAMP. The tools run from the source tree, so no colcon build is needed.
#
#   make maps          rebuild the nav2 maps whose source or tools changed
#   make maps-check    rebuild every map in a temporary directory and compare byte for byte
#   make maps-sources  redraw maps/src/*.png with maps/src/draw_sources.py (deterministic)
#   make maps-images   draw docs/images/maps/<name>.png for the README

.PHONY: maps maps-check maps-sources maps-images

MAP_NAMES := lgfloor map1 floorplan simple-maze
MAP_RESOLUTION := 0.05
# Black or white blobs smaller than this many pixels are drawing dust or stray laser hits.
MAP_DESPECKLE := 6
# World pose (x y yaw) of each map's lower-left corner.
MAP_ORIGIN_lgfloor := -15 -15 0
MAP_ORIGIN_map1 := 0 0 0
MAP_ORIGIN_floorplan := 0 0 0
MAP_ORIGIN_simple-maze := 0 0 0

MAP_TOOL_SOURCES := ros2_ws/src/stealth_sim/stealth_sim/map_tools.py \
	$(addprefix ros2_ws/src/stealth_core/stealth_core/,occupancy_map.py yaml_fields.py)
MAP_TOOLS = PYTHONPATH=$(ROOT)/ros2_ws/src/stealth_sim:$(ROOT)/ros2_ws/src/stealth_core$${PYTHONPATH:+:$$PYTHONPATH} \
	$(PYTHON) -m stealth_sim.map_tools
MAPS_WORK := $(ROOT)/cache/maps

# Shell commands turning maps/src/$(1).png into $(2)/$(1).pgm + .yaml, via $(3)/$(1)_bw.png.
define map_commands
$(MAP_TOOLS) image-to-bw maps/src/$(1).png -o $(3)/$(1)_bw.png --despeckle $(MAP_DESPECKLE) && \
$(MAP_TOOLS) png-to-ros-map $(3)/$(1)_bw.png -o $(2)/$(1) \
	--resolution $(MAP_RESOLUTION) --origin $(MAP_ORIGIN_$(1))
endef

maps: $(foreach name,$(MAP_NAMES),maps/$(name).pgm) ## Rebuild maps/<name>.pgm + .yaml from maps/src/<name>.png

maps/%.pgm maps/%.yaml: maps/src/%.png $(MAP_TOOL_SOURCES) | $(VENV_STAMP)
	@mkdir -p $(MAPS_WORK)
	@echo "maps: $* <- maps/src/$*.png"
	@$(call map_commands,$*,maps,$(MAPS_WORK))

maps-check: | $(VENV_STAMP) ## Check that maps/*.pgm + .yaml are exactly what the tools make of maps/src
	@work=$$(mktemp -d); trap 'rm -rf "$$work"' EXIT; \
	$(foreach name,$(MAP_NAMES),$(call map_commands,$(name),$$work,$$work) && ) \
	for file in $(foreach name,$(MAP_NAMES),$(name).pgm $(name).yaml); do \
		cmp maps/$$file $$work/$$file || { echo "maps-check: maps/$$file differs"; exit 1; }; \
	done; \
	echo "maps-check: $(MAP_NAMES) match their sources byte for byte"

maps-sources: | $(VENV_STAMP) ## Redraw the map sources maps/src/<name>.png
	@$(PYTHON) maps/src/draw_sources.py

maps-images: $(foreach name,$(MAP_NAMES),docs/images/maps/$(name).png) ## Draw docs/images/maps/<name>.png

docs/images/maps/%.png: maps/%.yaml maps/%.pgm $(MAP_TOOL_SOURCES) | $(VENV_STAMP)
	@mkdir -p $(@D)
	@$(MAP_TOOLS) render $< -o $@ --title '$*'
