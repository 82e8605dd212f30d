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
#    removed), a model check of each against the nominal spec, one summary table, and
#    each export's run and figures under runs/;
# 4. `rbprops report`: one self-contained HTML page (estimates with intervals, figures,
#    warnings by stage, the model checks' verdicts).
#
# Variables: N (exports, default 24), OUT (default out/uff-campaign), PYTHON (needs numpy
# and pyuff), CARGO, BIN (the binaries' directory; with BIN=target/debug the debug build
# is used and nothing is built: `make -f pipelines/uff-campaign.mk BIN=target/debug`).

N ?= 24
OUT ?= out/uff-campaign
PYTHON ?= python3
CARGO ?= cargo
BIN ?= target/release
EXPORTS := $(OUT)/exports

.PHONY: all bin clean
all: $(OUT)/report.html

# Builds the release binaries when BIN is the release directory (the default).
bin:
	$(if $(filter target/release,$(BIN)),$(CARGO) build --release -p rbprops-cli,@test -x $(BIN)/rbprops || { echo "no $(BIN)/rbprops: build it first"; exit 1; })

$(EXPORTS)/truth.json: scripts/uff_campaign.py
	$(PYTHON) scripts/uff_campaign.py generate $(EXPORTS) --n $(N)

$(OUT)/init-spec.toml: $(EXPORTS)/truth.json | bin
	$(BIN)/rbprops init-spec $(EXPORTS)/run-01.uff -o $@

$(EXPORTS)/nominal.toml: $(OUT)/init-spec.toml
	$(PYTHON) scripts/uff_campaign.py fill-spec $< $(EXPORTS)/truth.json -o $@

$(OUT)/summary.csv: $(EXPORTS)/nominal.toml bin
	rm -rf $(OUT)/runs
	$(BIN)/rbprops campaign $(EXPORTS) -o $@ --runs $(OUT)/runs
	@echo "summary: $@ (estimates and model-check verdicts, one row per export and estimator)"

$(OUT)/report.html: $(OUT)/summary.csv
	$(BIN)/rbprops report $(OUT) -o $@ --title "UFF campaign: $(N) exports"
	@echo "report: $@ (one page: estimates, figures, warnings, model-check verdicts)"

clean:
	rm -rf $(OUT)
