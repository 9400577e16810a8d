#include "client/core_commands/gnuplot.h"

#include <cstdio>

#include "absl/strings/str_cat.h"

namespace totalgrad::cli {

bool IsPlotExtension(const std::string& extension) {
  return extension == ".svg" || extension == ".pdf" || extension == ".png";
}

std::string PlotExtensionHint() { return "the file must end in .svg, .pdf or .png"; }

std::string GnuplotTerminal(const std::string& extension, int width, int height) {
  if (extension == ".svg") {
    return absl::StrCat("set terminal svg size ", width, ",", height,
                        " dynamic noenhanced font \"sans,11\"\n");
  }
  if (extension == ".pdf") {
    // pdfcairo sizes in inches; 100 points per inch keeps the layouts' proportions.
    return absl::StrCat("set terminal pdfcairo size ", width / 100.0, "in,", height / 100.0,
                        "in noenhanced font \"sans,9\"\n");
  }
  return absl::StrCat("set terminal pngcairo size ", width, ",", height,
                      " noenhanced font \"sans,10\"\n");
}

std::string GnuplotQuote(const std::string& text) {
  std::string out = "\"";
  for (char c : text) {
    if (c == '"' || c == '\\') out += '\\';
    out += c;
  }
  return out + "\"";
}

namespace {

// `text` as one word for /bin/sh (single-quoted).
std::string ShellQuote(const std::string& text) {
  std::string out = "'";
  for (char c : text) {
    if (c == '\'') out += "'\\''";
    else out += c;
  }
  return out + "'";
}

}  // namespace

std::string RunGnuplot(const std::string& script_path, const std::string& first) {
  const std::string command = "gnuplot " + (first.empty() ? "" : "-e " + ShellQuote(first) + " ") +
                              ShellQuote(script_path) + " 2>&1";
  FILE* pipe = popen(command.c_str(), "r");
  if (pipe == nullptr) return "cannot run gnuplot (install gnuplot-nox)";
  std::string messages;
  char buffer[256];
  while (fgets(buffer, sizeof(buffer), pipe) != nullptr) messages += buffer;
  const int rc = pclose(pipe);
  if (rc != 0) return "gnuplot failed on " + script_path + " (is gnuplot-nox installed?): " + messages;
  return "";
}

}  // namespace totalgrad::cli
