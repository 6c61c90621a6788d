# Sourced by the install scripts: `apt_get ARGS...` runs apt-get, waiting (up to
# APT_WAIT_SECONDS, 300 by default) for another package manager to release its locks
# instead of failing. apt-get's own DPkg::Lock::Timeout covers dpkg's lock but not the
# package lists' (`apt-get update` fails at once with exit 100 while another apt holds
# /var/lib/apt/lists/lock), so the lists lock is retried here.
apt_get() {
    local deadline=$(( $(date +%s) + ${APT_WAIT_SECONDS:-300} ))
    local log status
    log="$(mktemp)"
    while true; do
        status=0
        "${SUDO[@]}" env DEBIAN_FRONTEND=noninteractive apt-get -o DPkg::Lock::Timeout="${APT_WAIT_SECONDS:-300}" "$@" 2> >(tee "$log" >&2) || status=$?
        wait  # for tee
        if [ "$status" -eq 0 ]; then
            rm -f "$log"
            return 0
        fi
        if grep -q "Could not get lock\|Unable to lock" "$log" && [ "$(date +%s)" -lt "$deadline" ]; then
            echo "apt-get: another package manager holds a lock; retrying in 5 s (until $(date -d "@$deadline" +%H:%M:%S))" >&2
            sleep 5
            continue
        fi
        rm -f "$log"
        return "$status"
    done
}
