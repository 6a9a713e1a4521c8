// CLI11's application class, declared: headers that only pass a CLI::App& include this, and the
// units that add options include <CLI/CLI.hpp> itself (a header of 4-5.5 s of compile per unit:
// docs/measurements/walkthrough.md, 2026-12-04).
#pragma once

namespace CLI {
class App;
}  // namespace CLI
