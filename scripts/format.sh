#!/usr/bin/env bash
# Applies the committed .clang-format to every C++ file of the repository: tracked, and new ones
# not yet added (git ls-files --others --exclude-standard), so a file is formatted before its commit.
# Usage: scripts/format.sh [--check]   (--check changes nothing and fails if a file would change)
set -euo pipefail
cd "$(dirname "$0")/.."
formatter=${CLANG_FORMAT:-clang-format}
command -v "$formatter" >/dev/null || { echo "error: no $formatter (Debian: apt-get install clang-format)" >&2; exit 1; }
mapfile -t files < <(git ls-files --cached --others --exclude-standard '*.cpp' '*.hpp' '*.h' '*.cc')
if [[ "${1:-}" == "--check" ]]; then
  "$formatter" --style=file --dry-run --Werror "${files[@]}"
  echo "${#files[@]} files formatted as .clang-format says"
else
  "$formatter" --style=file -i "${files[@]}"
  echo "formatted ${#files[@]} files"
fi
