// What every `--plot` of the CLI shares: the file types a picture may have,
// the gnuplot terminal for each, gnuplot's quoting, and running gnuplot on a
// script written beside the picture (so that `gnuplot FILE.gp` redraws it).
#ifndef TOTALGRAD_CLIENT_CORE_COMMANDS_GNUPLOT_H_
#define TOTALGRAD_CLIENT_CORE_COMMANDS_GNUPLOT_H_

#include <string>

namespace totalgrad::cli {

// ".svg", ".pdf" or ".png": the picture types every plot writes.
bool IsPlotExtension(const std::string& extension);

// "the file must end in .svg, .pdf or .png", for a flag's error message.
std::string PlotExtensionHint();

// The `set terminal` line for a picture of `width` x `height` points in
// the type of `extension` (svg, pdfcairo at 100 points per inch, or
// pngcairo), with enhanced text off (labels hold option names with
// underscores). Requires IsPlotExtension(extension).
std::string GnuplotTerminal(const std::string& extension, int width, int height);

// `text` as a gnuplot double-quoted string.
std::string GnuplotQuote(const std::string& text);

// Runs `gnuplot script_path`, with `first` (gnuplot commands, e.g.
// `format = "pdf"`) run before the script when not empty. Returns "" on
// success, else what went wrong with gnuplot's own messages (gnuplot
// missing, a script error).
std::string RunGnuplot(const std::string& script_path, const std::string& first = "");

}  // namespace totalgrad::cli

#endif  // TOTALGRAD_CLIENT_CORE_COMMANDS_GNUPLOT_H_
