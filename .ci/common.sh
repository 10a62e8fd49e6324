# Shared by the scripts in .ci/ (sourced, not run): the repository root, cargo on PATH, numbered
# step headings, a fatal-error helper, a temporary work directory and an apt-get install that
# survives the flaky first install seen on these machines.
#
# The sourcing script sets `script` (its name, for messages) and `work_prefix` (for mktemp)
# before sourcing.

root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
export PATH="${CARGO_HOME:-$HOME/.cargo}/bin:$PATH"
start=$SECONDS
steps=0

step() {
    steps=$((steps + 1))
    printf '\n== [%d] %s (%ds)\n' "$steps" "$*" "$((SECONDS - start))"
}

die() {
    echo "$script: error: $*" >&2
    exit 1
}

# A fresh temporary directory in $work, removed on exit unless KEEP=1.
make_work() {
    work="$(mktemp -d "/tmp/$work_prefix.XXXXXX")"
    if [ "${KEEP:-0}" = 1 ]; then
        echo "keeping $work"
    else
        trap 'rm -rf "$work"' EXIT
    fi
}

# apt-get install of the given packages (quietly, no recommends). A first install of many packages
# once died in a libsystemd0 upgrade on these machines; --fix-broken and one retry got past it.
apt_install() {
    export DEBIAN_FRONTEND=noninteractive
    echo "installing: $*"
    apt-get update -qq
    if ! apt-get install -y -qq --no-install-recommends "$@" >/dev/null; then
        echo "apt-get install failed; trying apt-get --fix-broken install and once more"
        apt-get --fix-broken install -y -qq >/dev/null
        apt-get install -y -qq --no-install-recommends "$@" >/dev/null
    fi
}
