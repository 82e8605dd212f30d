# A campaign of UFF exports end to end, as a test engineer runs one:
#
#   make -f pipelines/uff-campaign.mk            # from the repository root
#
# 1. exports: scripts/uff_campaign.py writes N analyser-style UFF files with pyuff (numpy
#    FRFs of one article, τ = 4 s exponential window, 0.1 % noise; every fifth has one
#    channel 6 % out of calibration), truth.json and campaign.toml;
# 2. nominal spec: `rbprops init-spec` on the first export (the recording's own ids), its
#    FILL IN placeholders completed from truth.json (a person would use the CAD model);
# 3. `rbprops campaign`: modal-fit | ni-select | rb-solve per export in parallel (window
#    removed), a model check of each against the nominal spec, one summary table.
#
# Variables: N (exports, default 24), OUT (default out/uff-campaign), PYTHON (needs numpy
# and pyuff), CARGO.

N ?= 24
OUT ?= out/uff-campaign
PYTHON ?= python3
CARGO ?= cargo
BIN ?= target/release
EXPORTS := $(OUT)/exports

.PHONY: all bin clean
all: $(OUT)/summary.csv

bin:
	$(CARGO) build --release -p rbprops-cli

$(EXPORTS)/truth.json: scripts/uff_campaign.py
	$(PYTHON) scripts/uff_campaign.py generate $(EXPORTS) --n $(N)

$(OUT)/init-spec.toml: $(EXPORTS)/truth.json | bin
	$(BIN)/rbprops init-spec $(EXPORTS)/run-01.uff -o $@

$(EXPORTS)/nominal.toml: $(OUT)/init-spec.toml
	$(PYTHON) scripts/uff_campaign.py fill-spec $< $(EXPORTS)/truth.json -o $@

$(OUT)/summary.csv: $(EXPORTS)/nominal.toml bin
	$(BIN)/rbprops campaign $(EXPORTS) -o $@
	@echo "summary: $@ (estimates and model-check verdicts, one row per export and estimator)"

clean:
	rm -rf $(OUT)
