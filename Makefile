# tavc: set up, test, benchmark and reproduce. Works from nothing but Python 3.11+ and the
# package index: every target that needs tavc builds .venv first.

PYTHON ?= python3
VENV := .venv
BIN := $(VENV)/bin
# The resolved versions every install is constrained to (requirements.lock, `make lock`)
LOCK := requirements.lock
# Reinstall only when the dependencies change: the tool, then the test tools beside it.
STAMP := $(VENV)/.installed-stamp
TEST_STAMP := $(VENV)/.test-installed-stamp
# One reproduce-NAME target per experiment file (conf/experiment/NAME.yaml)
EXPERIMENTS := $(sort $(basename $(notdir $(wildcard conf/experiment/*.yaml))))
REPRODUCE := $(addprefix reproduce-,$(EXPERIMENTS))

.DEFAULT_GOAL := help
# Learning values [w_high, w_low] for the value-ratio sweep: ratios 1.0, 1.1 (the chapter's), 1.25 ... 2.0
VALUE_RATIOS := [2000,2000],[2200,2000],[2500,2000],[3000,2000],[3500,2000],[4000,2000]

comma := ,
empty :=
space := $(empty) $(empty)

# The chapter's base case, as its registry names it (read once, by the first recipe that needs it;
# a registry that cannot be read stops make, rather than leaving the name empty)
BASE = $(eval BASE := $(shell $(BIN)/python -c "from tavc_cli.chapter import base_case; print(base_case().name)"))$(or \
	$(BASE),$(error cannot read the chapter's base case from its registry with $(BIN)/python))
# The targets make the committed results, the chapter's experiments only: config folders of one's
# own that the shell names (tavc --config-dir) are not passed on to them
unexport TAVC_CONFIG_DIRS

# The horizon ladder: multiples of the chapter's durations at which the base case runs
LADDER ?= 1,4,10,20,40
# Trials per process at scale=converged: small batches spread hours of trees evenly over the
# cores, and a killed run loses less (batching changes speed, never numbers)
CONVERGED_BATCH ?= 2

.PHONY: help install venv venv-test lock lint test test-slow test-fast bench compare surrogate-study verify-outcomes reproduce-all reproduce-experiments reproduce-quick reproduce-converged ladder model value-ratio value-ratio-converged stay-switch stay-switch-calibrated readings-experiments turn-taking-readings readings-experiments-converged readings-x80 turn-taking-checks team-size-checks small-team-value-checks switch-checks firm-checks transition-predictions transition-runs transition-checks value-ratio-checks calibrate-readings $(REPRODUCE) clean

help: ## List the targets
	@awk 'BEGIN {FS = ":.*## "} /^[a-zA-Z0-9_-]+:.*## / {printf "  %-15s %s\n", $$1, $$2}' $(MAKEFILE_LIST)
	@echo "  reproduce-NAME  Run one experiment at paper scale ($(EXPERIMENTS))"

install: venv ## The tool alone: .venv with tavc at the locked versions, no test tools (the same as venv)

venv: $(STAMP) ## Create .venv and install tavc at the locked versions (requirements.lock)

# Installs under the lock's constraints: with uv (itself at the lock's version, fetched by pip),
# which installs the same set twice as fast as pip, compiled to bytecode as pip leaves it
# (without, the tests ran a fifth longer, most likely in processes that may not write into .venv
# and so compile what they import each time); where uv cannot be fetched or fails (a package
# index only pip is set up to reach), with pip
locked_install = ($(BIN)/python -m pip install -q -c $(LOCK) uv \
	&& $(BIN)/python -m uv pip install --compile-bytecode --python $(BIN)/python -c $(LOCK) $(1)) \
	|| ($(BIN)/python -m pip install --upgrade pip && $(BIN)/python -m pip install -c $(LOCK) $(1))

$(STAMP): pyproject.toml $(LOCK)
	$(PYTHON) -m venv $(VENV)
	$(call locked_install,-e .)
	touch $@

venv-test: $(TEST_STAMP) ## Add the test, lint, docs and cluster tools to .venv, at the locked versions

$(TEST_STAMP): $(STAMP)
	$(call locked_install,-e '.[test]')
	touch $@

LOCK_VENV ?= /tmp/tavc-lock-venv
lock: ## Resolve the newest versions pyproject.toml allows in a scratch venv and write them to requirements.lock
	rm -rf $(LOCK_VENV)
	$(PYTHON) -m venv $(LOCK_VENV)
	$(LOCK_VENV)/bin/python -m pip install -q --upgrade pip
	$(LOCK_VENV)/bin/python -m pip install -q -e '.[test]'
	head -3 $(LOCK) > $(LOCK).new
	$(LOCK_VENV)/bin/python -m pip freeze --exclude-editable >> $(LOCK).new
	mv $(LOCK).new $(LOCK)

lint: venv-test ## Check the code with ruff (its rules are in pyproject.toml)
	$(BIN)/ruff check tavc_cli tests

# Test files are spread over the cores whole (--dist loadfile), so each file's module-scoped
# runs are made once; `make test` and `make test-slow` together run every test.
PYTEST_PARALLEL ?= -n auto --dist loadfile
# The tests `make test` runs, as pytest's -m selects them; empty: every test, the slow ones among
# the others in one session (what CI runs: a file's runs made once for both kinds, and one end
# for the cores to wait at instead of two)
TESTS ?= not slow

test: venv-test lint ## Lint, then run the tests not marked slow (TESTS= for every test), in parallel
	$(BIN)/python -m pytest -q $(PYTEST_PARALLEL) $(if $(TESTS),-m "$(TESTS)")

test-slow: venv-test ## Run the tests marked slow (long end-to-end runs), in parallel
	$(BIN)/python -m pytest -q $(PYTEST_PARALLEL) -m slow

test-fast: venv-test ## Run the tests not marked slow in one process, without the lint
	$(BIN)/python -m pytest -q -m "not slow"

bench: venv ## Print simulator throughput as one JSON object
	$(BIN)/tavc bench --json

.PHONY: docs report-html
docs: venv-test ## Build the documentation site offline into site/, the report's page under site/report/
	$(BIN)/mkdocs build --strict
	mkdir -p site/report/converged
	cp results/REPORT.html site/report/index.html
	cp -r results/figures site/report/
	cp -r results/converged/figures site/report/converged/

report-html: venv ## Write results/REPORT.md and its web page results/REPORT.html (offline, a table of contents)
	$(BIN)/tavc report results --html

# Where verify-outcomes recomputes; the committed tables it must match byte for byte
VERIFY_DIR ?= /tmp/tavc-verify
VERIFY_RUN := state_time trial_stats performance allocation robots q_values claims comparison
VERIFY_WORLD := search sensitivity

verify-outcomes: venv ## Recompute the base case (initial_distribution) and the world search at paper scale; tables must match the committed ones byte for byte
	rm -rf $(VERIFY_DIR)
	$(BIN)/tavc run experiment=$(BASE) scale=paper output_dir=$(VERIFY_DIR)/$(BASE)
	$(BIN)/tavc calibrate scale=paper output_dir=$(VERIFY_DIR)
	@for f in $(VERIFY_RUN); do cmp results/$(BASE)/$$f.csv $(VERIFY_DIR)/$(BASE)/$$f.csv || exit 1; done
	@for f in $(VERIFY_WORLD); do cmp results/calibration/world/$$f.csv $(VERIFY_DIR)/calibration/world/$$f.csv || exit 1; done
	@echo "outcomes identical: $(words $(VERIFY_RUN)) tables of $(BASE), $(words $(VERIFY_WORLD)) of the world search"

# The experiments (one run of every core) beside the model. The model runs at the lowest
# priority, so that its trials take only the cores the experiments leave idle (their last
# trees, their analysis) and then the rest, rather than sharing the cores from the start.
REPRODUCE_JOBS ?= 2
MODEL_NICE ?=

reproduce-all: venv ## Run every experiment and the model at paper scale, then write results/REPORT.md; prints the wall time
	@date +%s > $(VENV)/.reproduce-start
	$(MAKE) -j$(REPRODUCE_JOBS) --output-sync=target --no-print-directory reproduce-experiments model \
		MODEL_NICE="$$(command -v nice >/dev/null && echo nice -n 19)"
	$(BIN)/tavc report results --html
	@echo "reproduce-all: $$(( $$(date +%s) - $$(cat $(VENV)/.reproduce-start) )) s wall time"

reproduce-experiments: venv ## Every experiment at paper scale in one run: the history their trials share simulated once
	$(BIN)/tavc reproduce scale=paper --results results

reproduce-converged: venv ## Every experiment and the horizon ladder at 40x the chapter's durations into results/converged/, then the report; prints the wall time
	@date +%s > $(VENV)/.converged-start
	$(BIN)/tavc reproduce scale=converged executor.batch_size=$(CONVERGED_BATCH) --results results/converged --ladder $(LADDER)
	$(BIN)/tavc report results --html
	@echo "reproduce-converged: $$(( $$(date +%s) - $$(cat $(VENV)/.converged-start) )) s wall time"

ladder: venv ## The base case (initial_distribution) at 1x to 40x the chapter's durations (results/converged/ladder/), the rungs' history shared
	$(BIN)/tavc ladder --factors $(LADDER) --results results/converged executor.batch_size=$(CONVERGED_BATCH)

reproduce-quick: venv ## A first look: every experiment at scale=quick into runs/quick/, and its report (not a verdict)
	@date +%s > $(VENV)/.reproduce-start
	$(BIN)/tavc reproduce scale=quick
	$(BIN)/tavc report runs/quick
	@echo "reproduce-quick: $$(( $$(date +%s) - $$(cat $(VENV)/.reproduce-start) )) s wall time"

model: venv ## Measure the vacancy-chain model in the chapter's world (results/initial_distribution/model/)
	$(MODEL_NICE) $(BIN)/tavc model experiment=$(BASE) scale=paper output_dir=results/$(BASE)

# the chapter's task-allocation experiments besides its base case, from the registry (those `tavc compare` serves)
OTHER_SCENARIOS = $(shell $(BIN)/python -c "from tavc_cli.chapter import base_case; from tavc_cli.compare import \
	SCENARIOS; print(' '.join(s for s in SCENARIOS if s != base_case().name))")

turn-taking-checks: venv ## The turn-taking model beside the chapter's at the chapter's other scenarios and values in today's world (results/turn_taking/)
	for e in $(OTHER_SCENARIOS); do \
		$(BIN)/tavc model --turn-taking experiment=$$e scale=paper output_dir=results/turn_taking/$$e || exit 1; done
	for w in 2000 3000 4000; do \
		$(BIN)/tavc model --turn-taking experiment=$(BASE) "tasks.values=[$$w,2000]" scale=paper \
			output_dir=results/turn_taking/value_ratio_$$w || exit 1; done

# Team sizes for the turn-taking model's checks against the learners at 40x (six, the chapter's, is
# checked by the base case's own run at results/converged/initial_distribution). In today's world, or in
# a reading named as its runs' folder is (READING=<arrival>-<passing>-<arena>, e.g.
# READING=dock-nearest-two_circuits_parallel, or range-left-two_circuits_parallel-calibrated for that reading at
# the settings its calibration chose, RANGE_CALIBRATED): the model into results/turn_taking/<reading>-team_size_N/,
# the learners into results/team_size/<reading>/converged/.
TEAM_SIZES := 2,3,4,5,7,8,9,10
READING :=
OTHER_READINGS = $(shell $(BIN)/python -c "from tavc_cli.analysis.stay_switch import reading_folder, readings; \
	print(' '.join(reading_folder(r) for r in readings()[1:]))") $(CALIBRATED_READING)
READING_ERROR = $(if $(and $(filter 1,$(words x$(READING)x)),$(filter $(OTHER_READINGS),$(READING))),,READING=$(READING) \
	is not one of the readings besides today's world ($(OTHER_READINGS)); leave READING out for today's world)
# The settings of the reading named $(1) (a folder name as READING's)
reading_args = $(if $(filter $(CALIBRATED_READING),$(1)),$(RANGE_CALIBRATED),arrival=$(word 1,$(subst -, ,$(1))) \
	passing=$(word 2,$(subst -, ,$(1))) arena=$(word 3,$(subst -, ,$(1))))
# Stops make with READING_ERROR where READING is set but not a reading; expands to nothing
check_reading = $(if $(READING),$(if $(READING_ERROR),$(error $(READING_ERROR))))
READING_ARGS = $(check_reading)$(if $(READING),$(call reading_args,$(READING)))

# The learners at 40x without baselines, $(1) trials each, in the reading whose settings are $(2)
learners_40x = experiment=$(BASE) scale=converged trials=$(1) 'baselines=[]' $(2)
# The learners at 40x without baselines in READING (today's world if left out), $(1) trials each, as a sweep; the
# caller adds the team, the values and the output folder
run_converged = $(BIN)/tavc run -m $(call learners_40x,$(1),$(READING_ARGS)) executor.batch_size=$(CONVERGED_BATCH)
# The turn-taking model both ways of measuring a lone switcher, for $(1) robots at $(2) against 2000 in the reading
# named $(3) (today's world if empty): today's way into results/turn_taking/[<reading>-]team_size_N-value_ratio_W/,
# the explorers' into the same name with -explorers (a shell loop: it exits at the first failure)
predict_both_ways_in = for s in "" explorers; do $(BIN)/tavc model --turn-taking experiment=$(BASE) team.n_robots=$(1) \
	"tasks.values=[$(2),2000]" scale=paper $(if $(3),$(call reading_args,$(3))) $${s:+surrogate.switches=$$s} \
	output_dir=results/turn_taking/$(if $(3),$(3)-)team_size_$(1)-value_ratio_$(2)$${s:+-$$s} || exit 1; done
# The same in READING (checked: check_reading)
predict_both_ways = $(check_reading)$(call predict_both_ways_in,$(1),$(2),$(READING))
# Values $(1) (space-separated) against 2000 as one multirun setting
values_against_2000 = 'tasks.values=$(subst $(space),$(comma),$(foreach w,$(1),[$(w),2000]))'

team-size-checks: venv ## The turn-taking model at team sizes 2-10 (results/turn_taking/team_size_N/), then the learners at 40x there (results/team_size/converged/); READING=<arrival>-<passing>-<arena> (or range-left-two_circuits_parallel-calibrated) for a reading
	for n in $(subst $(comma), ,$(TEAM_SIZES)); do \
		$(BIN)/tavc model --turn-taking experiment=$(BASE) team.n_robots=$$n scale=paper $(READING_ARGS) \
			output_dir=results/turn_taking/$(if $(READING),$(READING)-)team_size_$$n || exit 1; done
	$(call run_converged,8) team.n_robots=$(TEAM_SIZES) output_dir=results/team_size/$(if $(READING),$(READING)/)converged

# Small teams at other values (docs/readings.md): the turn-taking model's predictions with both ways of
# measuring a lone switcher (the default's into results/turn_taking/<reading>-team_size_N-value_ratio_W/,
# the explorers' into the same name with -explorers), then the learners at 40x into
# results/team_size/<reading>/converged_values/ (today's world: READING left out)
SMALL_TEAMS := 3,4
SMALL_TEAM_VALUES := 3000 4000

small-team-value-checks: venv ## The turn-taking model, both ways of measuring a lone switcher, at teams of 3 and 4 and the values 3000 and 4000 against 2000, then the learners at 40x there; READING as for team-size-checks
	for n in $(subst $(comma), ,$(SMALL_TEAMS)); do for w in $(SMALL_TEAM_VALUES); do \
		$(call predict_both_ways,$$n,$$w); done; done
	$(call run_converged,8) team.n_robots=$(SMALL_TEAMS) $(call values_against_2000,$(SMALL_TEAM_VALUES)) \
		output_dir=results/team_size/$(if $(READING),$(READING)/)converged_values

# The second grid of docs/readings.md: the points where the two ways of measuring a lone switcher name
# different regimes (reading:robots:w_high); both predictions, then the learners at 40x into
# results/team_size/<reading>/converged_switches/team_size_N-value_ratio_W/
SWITCH_POINTS := dock-nearest-two_circuits_parallel:3:2000 dock-left-two_circuits_parallel:3:2000 \
	dock-left-two_circuits_parallel:4:2400 range-left-two_circuits_parallel-calibrated:4:2400 \
	dock-left-two_circuits_parallel:5:2000

part = $(word $(2),$(subst :, ,$(1)))
# $(1) reading, $(2) robots, $(3) w_high
switch_run = $(BIN)/tavc run $(call learners_40x,8,$(call reading_args,$(1))) team.n_robots=$(2) \
	"tasks.values=[$(3),2000]" executor.batch_size=$(CONVERGED_BATCH) \
	output_dir=results/team_size/$(1)/converged_switches/team_size_$(2)-value_ratio_$(3)

switch-checks: venv ## The turn-taking model both ways, then the learners at 40x, at the points where the two ways of measuring a lone switcher differ (SWITCH_POINTS)
	$(foreach p,$(SWITCH_POINTS),$(call predict_both_ways_in,$(call part,$(p),2),$(call part,$(p),3),$(call part,$(p),1)) && ) true
	$(foreach p,$(SWITCH_POINTS),$(call switch_run,$(call part,$(p),1),$(call part,$(p),2),$(call part,$(p),3)) && ) true

# The third grid of docs/readings.md: teams of 3 to 6 at 2600 against 2000, with the chapter's 20 trials so that
# the learners' trials name their modal state more firmly than eight do; both predictions (the explorers' is the
# model's since the second grid), then the learners at 40x into results/team_size/<reading>/converged_firm/
FIRM_TEAMS := 3,4,5,6
FIRM_VALUE := 2600
FIRM_TRIALS := 20

firm-checks: venv ## The turn-taking model both ways at teams of 3 to 6 and 2600 against 2000, then the learners at 40x with 20 trials there; READING as for team-size-checks
	for n in $(subst $(comma), ,$(FIRM_TEAMS)); do $(call predict_both_ways,$$n,$(FIRM_VALUE)); done
	$(call run_converged,$(FIRM_TRIALS)) team.n_robots=$(FIRM_TEAMS) "tasks.values=[$(FIRM_VALUE),2000]" \
		output_dir=results/team_size/$(if $(READING),$(READING)/)converged_firm

# The fourth grid of docs/readings.md: three robots between the values where the learners of the parallel dock
# readings held 2:1 (2200, team-size-checks) and 3:0 (2600, firm-checks), with the chapter's 20 trials; both
# predictions (transition-predictions, committed before the runs), then the learners at 40x into
# results/team_size/<reading>/converged_transition/ (transition-runs); the fifth grid is the same at 2100
# (TRANSITION_VALUES=2100 TRANSITION_RUNS=converged_transition_2100)
TRANSITION_TEAM := 3
TRANSITION_VALUES := 2300 2400 2500
TRANSITION_TRIALS := 20
TRANSITION_RUNS := converged_transition

transition-predictions: venv ## The turn-taking model both ways for TRANSITION_TEAM robots at TRANSITION_VALUES against 2000; READING as for team-size-checks
	for w in $(TRANSITION_VALUES); do $(call predict_both_ways,$(TRANSITION_TEAM),$$w); done

transition-runs: venv ## The learners at 40x with TRANSITION_TRIALS trials for TRANSITION_TEAM robots at TRANSITION_VALUES against 2000; READING as for team-size-checks
	$(call run_converged,$(TRANSITION_TRIALS)) team.n_robots=$(TRANSITION_TEAM) $(call \
		values_against_2000,$(TRANSITION_VALUES)) output_dir=results/team_size/$(if $(READING),$(READING)/)$(TRANSITION_RUNS)

transition-checks: venv ## The fourth grid of docs/readings.md: transition-predictions, then transition-runs (in that order, also under -j)
	$(MAKE) transition-predictions
	$(MAKE) transition-runs

# The values of turn-taking-checks (today's world) in a reading: the model into
# results/turn_taking/<reading>-value_ratio_W/, then the learners at 40x into
# results/value_ratio/<reading>/converged/ (the base case's 2200/2000 is the reading's own 40x run)
VALUE_RATIO_CHECKS := 2000 3000 4000

value-ratio-checks: venv ## The turn-taking model at other values in a reading (READING=<arrival>-<passing>-<arena>, or range-left-two_circuits_parallel-calibrated), then the learners at 40x there
	$(if $(READING),,$(error value-ratio-checks needs READING=<arrival>-<passing>-<arena>; today's world's are turn-taking-checks and value-ratio-converged))
	for w in $(VALUE_RATIO_CHECKS); do \
		$(BIN)/tavc model --turn-taking experiment=$(BASE) "tasks.values=[$$w,2000]" scale=paper $(READING_ARGS) \
			output_dir=results/turn_taking/$(READING)-value_ratio_$$w || exit 1; done
	$(call run_converged,8) $(call values_against_2000,$(VALUE_RATIO_CHECKS)) output_dir=results/value_ratio/$(READING)/converged

# The readings of the world besides today's (docs/readings.md), arrival-passing-arena, and the grid each
# is calibrated on: a dock reading on today's (conf/config.yaml, calibration.grid), a range reading on its own
DOCK_READINGS := dock-left-two_circuits dock-nearest-two_circuits_parallel dock-left-two_circuits_parallel
RANGE_READINGS := range-nearest-two_circuits range-nearest-two_circuits_parallel range-left-two_circuits \
	range-left-two_circuits_parallel
RANGE_GRID := [{key:robot.behaviour.read_range_m,values:[1.0,1.5,2.0]},{key:robot.dock.dwell_s,values:[0.0,5.0,10.0]},{key:robot.laser.n_rays,values:[31,61]}]

calibrate-readings: venv ## Each reading's calibration search against the chapter's facts (results/readings/<reading>/calibration/world/)
	for r in $(DOCK_READINGS); do set -- $$(echo $$r | tr - ' '); \
		$(BIN)/tavc calibrate scale=paper arrival=$$1 passing=$$2 arena=$$3 \
			output_dir=results/readings/$$r || exit 1; done
	for r in $(RANGE_READINGS); do set -- $$(echo $$r | tr - ' '); \
		$(BIN)/tavc calibrate scale=paper arrival=$$1 passing=$$2 arena=$$3 'calibration.grid=$(RANGE_GRID)' \
			output_dir=results/readings/$$r || exit 1; done

# The chapter's five task-allocation experiments in other readings: labelled counterfactuals (docs/readings.md)
# (the registry's task-allocation experiments, those `tavc compare` serves; read only when a target uses them)
EXPERIMENTS_1_5 = $(shell $(BIN)/python -c "from tavc_cli.compare import SCENARIOS; print(','.join(SCENARIOS))")
DOCK_PARALLEL := dock-left-two_circuits_parallel dock-nearest-two_circuits_parallel
READINGS_1X := range-left-two_circuits_parallel $(DOCK_PARALLEL)
# the range/left/parallel reading at the settings its calibration search chose, and its runs' folder name
RANGE_CALIBRATED := arrival=range passing=left arena=two_circuits_parallel robot.behaviour.read_range_m=2.0 \
	robot.dock.dwell_s=5.0 robot.laser.n_rays=31
CALIBRATED_READING := range-left-two_circuits_parallel-calibrated

readings-experiments: venv ## The chapter's five task-allocation experiments at its durations in other readings (results/readings/<reading>/)
	for r in $(READINGS_1X); do set -- $$(echo $$r | tr - ' '); \
		$(BIN)/tavc reproduce scale=paper --experiments $(EXPERIMENTS_1_5) arrival=$$1 passing=$$2 arena=$$3 \
			--results results/readings/$$r || exit 1; done
	$(BIN)/tavc reproduce scale=paper --experiments $(EXPERIMENTS_1_5) $(RANGE_CALIBRATED) \
		--results results/readings/$(CALIBRATED_READING)

turn-taking-readings: venv ## The turn-taking model in the readings whose experiments run at 40x, before those runs are read (results/turn_taking/)
	$(BIN)/tavc model --turn-taking experiment=$(BASE) scale=paper $(RANGE_CALIBRATED) \
		output_dir=results/turn_taking/$(CALIBRATED_READING)
	for e in $(OTHER_SCENARIOS); do \
		$(BIN)/tavc model --turn-taking experiment=$$e scale=paper $(RANGE_CALIBRATED) \
			output_dir=results/turn_taking/$(CALIBRATED_READING)-$$e || exit 1; done
	for r in $(DOCK_PARALLEL); do set -- $$(echo $$r | tr - ' '); for e in $(OTHER_SCENARIOS); do \
		$(BIN)/tavc model --turn-taking experiment=$$e scale=paper arrival=$$1 passing=$$2 arena=$$3 \
			output_dir=results/turn_taking/$$r-$$e || exit 1; done; done

readings-experiments-converged: venv ## The same experiments at 40x, 8 trials, in both parallel dock readings and the calibrated range world (results/converged/readings/)
	for r in $(DOCK_PARALLEL); do set -- $$(echo $$r | tr - ' '); \
		$(BIN)/tavc reproduce scale=converged trials=8 baseline_trials=8 executor.batch_size=$(CONVERGED_BATCH) \
			--experiments $(EXPERIMENTS_1_5) arrival=$$1 passing=$$2 arena=$$3 \
			--results results/converged/readings/$$r || exit 1; done
	$(BIN)/tavc reproduce scale=converged trials=8 baseline_trials=8 executor.batch_size=$(CONVERGED_BATCH) \
		--experiments $(EXPERIMENTS_1_5) $(RANGE_CALIBRATED) \
		--results results/converged/readings/$(CALIBRATED_READING)

readings-x80: venv ## The base case at 80x, 8 trials, in the parallel readings (and the calibrated range world) whose learners had not settled by 40x (results/x80/readings/)
	$(BIN)/tavc run experiment=$(BASE) scale=converged scale.time_factor=80 trials=8 baseline_trials=8 \
		arrival=range passing=left arena=two_circuits_parallel output_dir=results/x80/readings/range-left-two_circuits_parallel
	$(BIN)/tavc run experiment=$(BASE) scale=converged scale.time_factor=80 trials=8 baseline_trials=8 \
		arrival=dock passing=left arena=two_circuits_parallel output_dir=results/x80/readings/dock-left-two_circuits_parallel
	$(BIN)/tavc run experiment=$(BASE) scale=converged scale.time_factor=80 trials=8 baseline_trials=8 \
		$(RANGE_CALIBRATED) output_dir=results/x80/readings/$(CALIBRATED_READING)

stay-switch: venv ## What each reading of the world does to staying and switching: static robots in every make-up (results/stay_switch/)
	$(BIN)/tavc stay-switch scale=paper --results results/stay_switch

stay-switch-calibrated: venv ## The same with each reading at the settings its calibration search chose (results/stay_switch_calibrated/)
	$(BIN)/tavc stay-switch scale=paper --calibrated results --results results/stay_switch_calibrated

value-ratio: venv ## Share of time on the high-value circuit against the value ratio: 5 h and 50 h, t in ms and s; gamma 0 at 5 h
	$(BIN)/tavc run -m experiment=$(BASE) scale=paper 'baselines=[]' tasks.time_unit=ms,s \
		'tasks.values=$(VALUE_RATIOS)' output_dir=results/value_ratio/paper
	$(BIN)/tavc run -m experiment=$(BASE) scale=long 'baselines=[]' tasks.time_unit=ms,s \
		'tasks.values=$(VALUE_RATIOS)' output_dir=results/value_ratio/long
	$(BIN)/tavc run -m experiment=$(BASE) scale=paper 'baselines=[]' learner.gamma=0 \
		'tasks.values=$(VALUE_RATIOS)' output_dir=results/value_ratio/paper_gamma0

# The value-ratio sweep at 40x the chapter's 5 h (200 h), where the learning rule converges
VALUE_RATIOS_CONVERGED := [2000,2000],[2200,2000],[3000,2000],[4000,2000]

value-ratio-converged: venv ## The value-ratio sweep at 40x the chapter's durations: ratios 1.0, 1.1, 1.5, 2.0, 8 trials of 200 h
	$(BIN)/tavc run -m experiment=$(BASE) scale=converged trials=8 'baselines=[]' \
		executor.batch_size=$(CONVERGED_BATCH) 'tasks.values=$(VALUE_RATIOS_CONVERGED)' output_dir=results/value_ratio/converged

compare: venv ## Learners side by side on the chapter's scenarios at paper scale and at 40x (results/compare/)
	$(BIN)/tavc compare scale=paper --results results/compare/paper
	$(BIN)/tavc compare scale=converged scale.trials=8 executor.batch_size=$(CONVERGED_BATCH) \
		--results results/compare/converged --reuse tavc=results/converged

surrogate-study: venv ## The surrogate of the learning dynamics checked against results/ and its phase diagrams (results/surrogate/)
	$(BIN)/tavc surrogate --study --results results/surrogate --simulator results

$(REPRODUCE): reproduce-%: venv
	$(BIN)/tavc run experiment=$* scale=paper output_dir=results/$*

clean: ## Remove build artefacts and caches (keeps .venv and results/)
	rm -rf build dist *.egg-info .pytest_cache .ruff_cache
	find . -path ./$(VENV) -prune -o -name __pycache__ -type d -exec rm -rf {} +
