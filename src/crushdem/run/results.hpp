// The result files that describe a run as a whole: summary.json (what the run produced, the same
// for any thread count) and timing.json (where its wall-clock time went, the one file that
// varies), and the JSON records they are made of.
#pragma once

#include <cstddef>
#include <string>
#include <utility>

#include "crushdem/experiments/protocol.hpp"
#include "crushdem/experiments/stages.hpp"
#include "crushdem/fracture/crushing.hpp"
#include "crushdem/io/output.hpp"
#include "crushdem/run/checkpoint.hpp"

namespace crushdem {

/// One stage's entry of summary.json "stages".
JsonObject stage_json(const StageResult& r);

/// Shares of the crushable grains loaded to at least a fraction of their strength at the end of
/// a stage (Crusher::loaded_share), keyed by the fraction.
JsonObject loaded_share_json(const Simulation& sim, const Crusher& crusher);

/// summary.json "sample": the prepared sample against its targets.
JsonObject sample_json(const Simulation& sim, const SampleConfig& cfg,
                       const PreparationController& prep);

/// summary.json: the code that made it, the sample, the stages, the crushing measurements with
/// the solid mass balance, and the final state. branch_json: the text of branch.json ("" if the
/// run is no branch).
JsonObject summary_json(const RunPosition& position, const Simulation& sim, std::size_t snapshots,
                        const Crusher* crusher, const std::string& branch_json);

/// timing.json for `seconds` of wall-clock time (this process and the ones before it);
/// rewritten at every checkpoint (finished = false) so that a long or interrupted run shows
/// where its time goes. Returns the part of the step that took the most time and its share.
std::pair<std::size_t, double> write_timing(const std::string& path, const std::string& backend,
                                            bool finished, bool resumed, double seconds,
                                            double particle_steps, Simulation& sim);

}  // namespace crushdem
