//! The medium lane: one thread of its own for exchanges too costly for the dispatcher
//! thread but small, so that they need not queue behind a big batch on the worker pool.
//!
//! rayon's `spawn` queues FIFO and a running batch keeps every worker until it ends
//! (64 scan envs: 3–80 ms an exchange), so a 0.4 ms exchange handed to the pool waited
//! for all of it. The dispatcher sends such an exchange here instead while a big one is
//! on the pool (`transport::dispatcher`, "Exchanges off the dispatcher"); the lane runs
//! its tasks one after the other, each on this thread alone.

use std::panic::{AssertUnwindSafe, catch_unwind};
use std::sync::mpsc::{Sender, channel};
use std::thread::JoinHandle;

/// Work for the lane.
pub type LaneTask = Box<dyn FnOnce() + Send + 'static>;

/// The lane's thread and its queue.
pub struct Lane {
    queue: Option<Sender<LaneTask>>,
    thread: Option<JoinHandle<()>>,
}

impl Lane {
    /// Start the lane's thread at nice value `nice` (the workers').
    pub fn start(nice: i32) -> std::io::Result<Self> {
        let (queue, tasks) = channel::<LaneTask>();
        let thread = std::thread::Builder::new()
            .name("echogym-lane".to_owned())
            .spawn(move || {
                super::renice_this_thread(nice);
                for task in tasks {
                    // A task catches its own panics (an exchange does); this is the net
                    // under that net, so the lane outlives any task.
                    if let Err(payload) = catch_unwind(AssertUnwindSafe(task)) {
                        tracing::error!(
                            message = %super::panic_message(payload.as_ref()),
                            "a lane task panicked"
                        );
                    }
                }
            })?;
        Ok(Self {
            queue: Some(queue),
            thread: Some(thread),
        })
    }

    /// Queue `task` behind the lane's current work. Gives the task back if the lane's
    /// thread is gone (it is not expected to be: every task is caught).
    pub fn spawn(&self, task: LaneTask) -> Result<(), LaneTask> {
        match &self.queue {
            Some(queue) => queue.send(task).map_err(|e| e.0),
            None => Err(task),
        }
    }
}

impl Drop for Lane {
    /// Run what is queued, then stop the thread.
    fn drop(&mut self) {
        drop(self.queue.take());
        if let Some(thread) = self.thread.take() {
            let _ = thread.join();
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::sync::Arc;
    use std::sync::atomic::{AtomicUsize, Ordering};

    #[test]
    fn runs_tasks_in_order_and_survives_a_panic() {
        let lane = Lane::start(0).unwrap();
        let done = Arc::new(AtomicUsize::new(0));
        let order = Arc::new(std::sync::Mutex::new(Vec::new()));
        for i in 0..3 {
            let (done, order) = (done.clone(), order.clone());
            lane.spawn(Box::new(move || {
                order.lock().unwrap().push(i);
                done.fetch_add(1, Ordering::SeqCst);
                if i == 1 {
                    panic!("a task panics");
                }
            }))
            .unwrap_or_else(|_| panic!("lane gone"));
        }
        drop(lane); // waits for the queued tasks
        assert_eq!(done.load(Ordering::SeqCst), 3);
        assert_eq!(*order.lock().unwrap(), vec![0, 1, 2]);
    }
}
