# Recipes wrap plain scripts under scripts/, so `just` is optional.

# Run the whole pipeline on the default campaign and print the estimates.
demo example="demo":
    scripts/demo.sh {{example}}

# The test suite (what CI runs).
test:
    scripts/test.sh

# Regenerate the paper's tables and figures.
paper:
    scripts/paper.sh

# Run every campaign spec or recording under DIR in parallel, one summary table.
campaign dir:
    scripts/campaign.sh {{dir}}

# Benchmarks (release).
bench:
    cargo bench --workspace
