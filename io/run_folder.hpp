// The output folder of a run (README "Outputs: how a run replaces its folder").
//
// A run never writes into its folder DIR directly. It holds a lock (PARENT/.NAME.lock, flock) for
// as long as it runs, so that a second run into DIR is refused; it writes into the staging folder
// DIR.running beside DIR; and when every file is complete it publishes them in one step: DIR.running
// and DIR exchange names (renameat2 RENAME_EXCHANGE), the files of DIR that matep did not write
// move into the new DIR, and the previous run's outputs are deleted. DIR therefore always holds
// one complete set: the previous run's until the exchange, the new one after it.
// A run killed before it publishes leaves DIR untouched and its partial files in DIR.running,
// which the next run into DIR clears (carrying any user file left there back into DIR).
#pragma once

#include <string>

namespace matep {

// The names matep writes into an output folder (files and the snapshots/ folder): what a run
// replaces; anything else in the folder is the user's and stays.
bool is_run_output(const std::string& name);

class RunFolder {
 public:
  // Takes the lock, clears a stale staging folder and creates a fresh one. Throws SceneError-like
  // IoError (exit 2) when DIR is not a folder, is the working folder or holds it, or a live run
  // holds it; WriteError when the folders cannot be made.
  explicit RunFolder(const std::string& dir);
  // Not published: removes the staging folder (its files are incomplete) and the lock.
  ~RunFolder();
  RunFolder(const RunFolder&) = delete;
  RunFolder& operator=(const RunFolder&) = delete;

  const std::string& dir() const { return dir_; }          // where the outputs end up
  const std::string& staging() const { return staging_; }  // where the run writes them
  // Moves the staging folder's files into place as one set (signals held back meanwhile).
  void publish();
  // Where a killed run's staging folder with a checkpoint was kept (DIR.killed; empty: none was).
  const std::string& killed() const { return killed_; }

 private:
  std::string dir_, staging_, lock_path_, killed_;
  int lock_fd_ = -1;
  bool published_ = false;
};

}  // namespace matep
