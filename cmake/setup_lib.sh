# cmake/setup_lib.sh - the checks cmake/setup.sh makes, as functions a test can call alone
# (tests/setup_lib_test.sh runs each many times).
#
# Every function here is written for `set -euo pipefail`: no command's output is piped into one
# that may stop reading early (`grep -q`, `head`), since the writer is then killed by SIGPIPE and
# pipefail makes the pipeline fail at random. Output is captured first and matched in the shell.
# tests/lint_scripts.sh keeps that pattern out of every script in the tree.

# package_installed PACKAGE: true when dpkg reports PACKAGE as installed.
package_installed() {
  local status
  status="$(dpkg-query -W -f='${Status}' "$1" 2>/dev/null)" || return 1
  [[ "$status" == *"install ok installed"* ]]
}

# loads_library PROGRAM PREFIX: true when the dynamic loader resolves one of PROGRAM's libraries to
# a path that starts with PREFIX (as `ldd` lists it).
loads_library() {
  local listing line
  listing="$(ldd "$1")" || return 1
  while IFS= read -r line; do
    [[ "$line" == *"=> $2"* ]] && return 0
  done <<<"$listing"
  return 1
}

# derive_source_entries LIST_OUT PARTS_OUT: writes apt source entries of type deb-src for every
# deb entry apt is configured with (one-line sources.list files and deb822 .sources files), so
# that source packages come from wherever this machine takes its binary packages.
derive_source_entries() {
  local list_out="$1" parts_out="$2" file
  mkdir -p "$parts_out"
  : >"$list_out"
  local lists=()
  [ -f /etc/apt/sources.list ] && lists+=(/etc/apt/sources.list)
  for file in /etc/apt/sources.list.d/*.list; do
    [ -f "$file" ] && lists+=("$file")
  done
  for file in "${lists[@]}"; do
    sed -n 's/^[[:space:]]*deb[[:space:]]/deb-src /p' "$file" >>"$list_out"
  done
  for file in /etc/apt/sources.list.d/*.sources; do
    [ -f "$file" ] || continue
    sed 's/^Types:.*$/Types: deb-src/' "$file" >"$parts_out/$(basename "$file")"
  done
}

# fetch_debian_source PACKAGE VERSION INTO: downloads the Debian source package that builds binary
# PACKAGE at VERSION into INTO through apt (a private index of deb-src entries derived from the
# configured deb entries; apt checks every file against the signed index) and unpacks its upstream
# tarball into INTO/source. The system's own apt state is not touched.
fetch_debian_source() {
  local package="$1" version="$2" into="$3"
  local state="$into/apt"
  mkdir -p "$state/lists/partial" "$state/cache/archives/partial" "$into/source"
  derive_source_entries "$state/sources.list" "$state/sources.list.d"
  local apt_options=(-o "Dir::Etc::SourceList=$state/sources.list" -o "Dir::Etc::SourceParts=$state/sources.list.d"
                     -o "Dir::State::Lists=$state/lists" -o "Dir::Cache=$state/cache" -o "Debug::NoLocking=1")
  # as root, apt would hand the download to its _apt user, who cannot write into the build tree
  if [ "$(id -u)" -eq 0 ]; then apt_options+=(-o "APT::Sandbox::User=root"); fi
  # an entry whose host publishes no sources only warns; the source command below says what is missing
  apt-get "${apt_options[@]}" -qq update || true
  local source_name source_version
  source_name="$(dpkg-query -W -f='${source:Package}' "$package")"
  source_version="$(dpkg-query -W -f='${source:Version}' "$package")"
  [ "$source_version" = "$version" ] || echo "setup: $package $version is built from $source_name $source_version"
  (cd "$into" && apt-get "${apt_options[@]}" -qq --download-only source "$source_name=$source_version") || {
    echo "setup: apt found no source package $source_name $source_version (deb-src entries derived from the configured deb entries)" >&2
    return 1
  }
  local tarball
  for tarball in "$into"/*.orig.tar.*; do
    [ -f "$tarball" ] || continue
    tar -xf "$tarball" -C "$into/source"
    return 0
  done
  echo "setup: the source package $source_name $version has no upstream tarball" >&2
  return 1
}
