// The SVA's box filter stage, as the chip plan describes it (sva/box/timing.py: box_stage,
// "box_filter": II = max(G, column sums' ports), latency G + tree(2) + tree(lg(k) + 1)); the sums
// are sva/box/aggregation.py's (box_filter_ref: k x k window, replicate borders, saturating at
// 2^A_W - 1 = 2^cost_bits - 1).
//
// Interface (a stage of a lock-step pipeline; a later SVA top chains it):
// - en: the pipeline advances this cycle (0: every register and memory port holds -- the
//   model's stall);
// - a slot is taken in a cycle with en, in_valid and in_ready; it carries the D costs of the
//   column `col` it updates, of the row entering the vertical window (c_add) and of the row
//   leaving it (c_sub), and its control: upd (update column col's sums: else the newest column
//   sum re-enters the row window unchanged -- the right border's replicated column), fresh
//   (the column's old sum reads as 0: the first pass of a frame), fill (the row window is
//   filled with this column k times: a row's first column, the left border), emit (an output
//   pixel leaves for this slot);
// - run-time registers: ngroups = G = ceil(D / LANES), k (odd, <= K_MAX);
// - out_valid: for one advancing cycle (held while stalled), agg holds the D box sums of the
//   pixel whose window's right column the emitting slot brought.
// A row of W output pixels takes W + r slots (r = k / 2): columns 0 .. r - 1 (no emit), then
// columns r .. W - 1 (each emitting pixel col - r), then r slots without update (emitting
// W - r .. W - 1); a frame first takes k passes over its columns that add the rows clamp(-r)
// .. r (the first with fresh). The sequencing is the top's (tests/rtl/box_bench.py).
//
// Structure (the cycles come from it; nothing is delayed to meet a number):
// - slot taken in cycle t: lane group g (LANES disparities) reads its word of column col's
//   sums from the column-sum memory (W_MAX x G words of LANES sums, synchronous read) in cycle
//   t + g: a group a cycle, so II = G with a read and a write port (ONE_PORT = 0);
// - the column update, old + c_add - c_sub (two adder levels: tree(2) cycles, V levels a
//   cycle), is written back in its last cycle (cycle t + g + tree(2)) and registered;
// - ONE_PORT = 1 (sva.sram_ports = "1rw"): the memory has one port, one access a cycle (one
//   address, one write enable, the read register). Reads keep their cycles (a slot's groups
//   at t .. t + G - 1: the latency does not change); a write that meets a read waits in a
//   queue of pending writes and is written in the first cycle without a read. A slot is taken
//   when no write is still being computed and the writes waiting (queued or arriving) fit in
//   the cycles between its own reads and its own first write (tree(2) - G of them, none when
//   G >= tree(2)). So the next slot waits for an updating slot's G reads and its G writes:
//   II = 2 G; a slot that updates nothing (the right border's) writes nothing, and
//   the next is taken G cycles after it. A column is read again W slots later, long after
//   its writes;
// - the row sum: a window of the K_MAX newest column sums per disparity (registers), the
//   updated one with the k - 1 before it summed by a tree of lg(K_MAX) adder levels and one
//   level that saturates: tree(lg(K_MAX) + 1) cycles, into the output register.
// So a pixel leaves G + tree(2) + tree(lg(K_MAX) + 1) cycles after its slot is taken: the
// plan's rule (with k = K_MAX; its earlier G + 2 held only for V >= lg(K_MAX) + 1).
module sva_box #(
    parameter int D_MAX = 32,   // largest disparity range (build-time: the lanes' memory)
    parameter int LANES = 16,   // disparities a cycle
    parameter int V = 8,        // two-input adder/compare levels that settle in one cycle
    parameter int K_MAX = 7,    // largest box size
    parameter int W_MAX = 32,   // widest row (columns of the column-sum memory)
    parameter int COST_W = 6,   // bits of a matching cost
    parameter int A_W = 8,      // bits of a box sum: sva.cost_bits (saturating)
    parameter bit ONE_PORT = 0  // the column sums' memory: 0 a read and a write port, 1 one
) (
    input  logic                      clk,
    input  logic                      rst,
    input  logic                      en,
    input  logic [7:0]                ngroups,
    input  logic [3:0]                k,
    input  logic                      in_valid,
    output logic                      in_ready,
    input  logic [$clog2(W_MAX)-1:0]  col,
    input  logic                      upd,
    input  logic                      fresh,
    input  logic                      fill,
    input  logic                      emit,
    input  logic [D_MAX*COST_W-1:0]   c_add,
    input  logic [D_MAX*COST_W-1:0]   c_sub,
    output logic                      out_valid,
    output logic [D_MAX*A_W-1:0]      agg
);
  localparam int G_MAX = (D_MAX + LANES - 1) / LANES;
  localparam int GW = (G_MAX > 1) ? $clog2(G_MAX) : 1;
  localparam int CW = $clog2(W_MAX);
  localparam int CMAX = (1 << COST_W) - 1;
  localparam int CS_W = $clog2(K_MAX * CMAX + 1);           // a column sum: <= k C_max
  localparam int S_W = $clog2(K_MAX * K_MAX * CMAX + 1);     // a window sum: <= k^2 C_max
  localparam int KL = $clog2(K_MAX);                         // row-sum adder levels
  localparam int KN = 1 << KL;                               // leaves, a power of two
  localparam int CU_T = (2 + V - 1) / V;                     // column update: tree(2)
  localparam int RS_LEVELS = KL + 1;                         // + the saturation
  localparam int RS_T = (RS_LEVELS + V - 1) / V;             // row sum: tree(lg K_MAX + 1)
  localparam int WORD = LANES * CS_W;

  // ---- the slot's input register and the lane-group counter --------------------------------
  logic [CW-1:0]             col_q;
  logic                      upd_q, fresh_q, fill_q, emit_q;
  logic [D_MAX*COST_W-1:0]   add_q, sub_q;
  logic [GW-1:0]             group;
  logic                      busy;
  wire                       take = en && in_valid && in_ready;
  wire  [GW-1:0]             last_g = GW'(int'(ngroups) - 1);
  logic                      port_ok;   // the column-sum memory's port can take a slot
  assign in_ready = !busy && port_ok;   // the taken slot issues its group 0 itself
  always_ff @(posedge clk) begin
    if (rst) begin
      busy <= 1'b0;
      group <= '0;
    end else if (en) begin
      if (take) begin
        col_q <= col; upd_q <= upd; fresh_q <= fresh; fill_q <= fill; emit_q <= emit;
        add_q <= c_add; sub_q <= c_sub;
      end
      if (take && ngroups > 8'd1) begin
        busy <= 1'b1;
        group <= GW'(1);
      end else if (busy && group == last_g) begin
        busy <= 1'b0;
        group <= '0;
      end else if (busy) begin
        group <= group + 1'b1;
      end
    end
  end

  // the lane group issued this cycle (its column-sum word read): the taken slot's group 0, or
  // the counter's group of the slot in the input register
  wire                       iss_v = take || busy;
  wire  [GW-1:0]             iss_g = take ? '0 : group;
  wire  [CW-1:0]             iss_col = take ? col : col_q;

  // ---- the column-sum memory: W_MAX x G_MAX words ------------------------------------------
  logic [WORD-1:0] mem [W_MAX * G_MAX];
  logic [WORD-1:0] rd_q;
  logic            wr_en;
  int              wr_addr;
  logic [WORD-1:0] wr_data;

  // ---- the column update: old + c_add - c_sub, tree(2) cycles -------------------------------
  // cu[0]: the cycle after the issue (the read word arrives); a register after every V levels
  logic            cu_v [CU_T + 1];
  logic [GW-1:0]   cu_g [CU_T + 1];
  logic            cu_last [CU_T + 1];
  logic [CW-1:0]   cu_col [CU_T + 1];
  logic            cu_upd [CU_T + 1], cu_fill [CU_T + 1], cu_emit [CU_T + 1];
  always_ff @(posedge clk) begin
    if (rst) cu_v[0] <= 1'b0;
    else if (en) cu_v[0] <= iss_v;
    if (en) begin
      cu_g[0] <= iss_g; cu_last[0] <= (iss_g == last_g); cu_col[0] <= iss_col;
      cu_upd[0] <= take ? upd : upd_q; cu_fill[0] <= take ? fill : fill_q;
      cu_emit[0] <= take ? emit : emit_q;
    end
  end
  logic            fresh_1;   // fresh of the slot whose group is in cu[0]
  always_ff @(posedge clk) if (en) fresh_1 <= take ? fresh : fresh_q;

  // the newest column sum of each disparity (a column not updated re-enters the window as it)
  logic [CS_W-1:0] newest [D_MAX];
  logic [CS_W-1:0] cs_new [LANES];           // the updated column's sums of the group, settled
  genvar ln;
  generate
    for (ln = 0; ln < LANES; ln++) begin : lane_cu
      logic [CS_W:0] added, subbed;
      always_comb begin
        int di;
        di = int'(cu_g[0]) * LANES + ln;
        added = (fresh_1 ? '0 : (CS_W + 1)'(rd_q[ln*CS_W +: CS_W]))
              + ((di < D_MAX) ? (CS_W + 1)'(add_q[di*COST_W +: COST_W]) : '0);
      end
      if (CU_T == 1) begin : one   // both levels in the read word's cycle
        always_comb begin
          int di;
          di = int'(cu_g[0]) * LANES + ln;
          subbed = added - ((di < D_MAX) ? (CS_W + 1)'(sub_q[di*COST_W +: COST_W]) : '0);
        end
      end else begin : two         // V = 1: a register between the add and the sub
        logic [COST_W-1:0] sub_d;
        logic [CS_W:0]     added_q;
        always_ff @(posedge clk) if (en) begin
          added_q <= added;
          sub_d <= (int'(cu_g[0]) * LANES + ln < D_MAX)
                   ? sub_q[(int'(cu_g[0]) * LANES + ln) * COST_W +: COST_W] : '0;
        end
        assign subbed = added_q - (CS_W + 1)'(sub_d);
      end
      always_comb begin
        int di;
        di = int'(cu_g[CU_T - 1]) * LANES + ln;
        cs_new[ln] = cu_upd[CU_T - 1] ? subbed[CS_W-1:0]
                   : ((di < D_MAX) ? newest[di] : '0);
      end
    end
  endgenerate
  genvar cs;
  generate
    for (cs = 1; cs < CU_T; cs++) begin : cu_pipe
      always_ff @(posedge clk) begin
        if (rst) cu_v[cs] <= 1'b0;
        else if (en) cu_v[cs] <= cu_v[cs-1];
        if (en) begin
          cu_g[cs] <= cu_g[cs-1]; cu_last[cs] <= cu_last[cs-1]; cu_col[cs] <= cu_col[cs-1];
          cu_upd[cs] <= cu_upd[cs-1]; cu_fill[cs] <= cu_fill[cs-1];
          cu_emit[cs] <= cu_emit[cs-1];
        end
      end
    end
  endgenerate
  // the write-back in the update's last cycle, and the newest column sums
  always_comb begin
    wr_en = cu_v[CU_T - 1] && cu_upd[CU_T - 1];
    wr_addr = int'(cu_col[CU_T - 1]) * G_MAX + int'(cu_g[CU_T - 1]);
    for (int i = 0; i < LANES; i++) wr_data[i*CS_W +: CS_W] = cs_new[i];
  end

  // the memory's ports (the reads at the lane groups' issue, the write-backs above)
  generate
    if (!ONE_PORT) begin : two_ports   // a read and a write port
      always_ff @(posedge clk) begin
        if (en && iss_v) rd_q <= mem[int'(iss_col) * G_MAX + int'(iss_g)];
        if (en && wr_en) mem[wr_addr] <= wr_data;
      end
      assign port_ok = 1'b1;
    end else begin : one_port          // one port; writes that meet a read wait in a queue
      // pending writes: a slot's own arriving while its later groups read (G - tree(2) at
      // most), or those waiting when it is taken (tree(2) - G at most, G = 1: one)
      localparam int QD = (G_MAX - CU_T > 1) ? G_MAX - CU_T : 1;
      localparam int QW = $clog2(QD + 1);
      localparam int AW = (W_MAX * G_MAX > 1) ? $clog2(W_MAX * G_MAX) : 1;
      logic [AW-1:0]   q_addr [QD];
      logic [WORD-1:0] q_data [QD];
      logic [QW-1:0]   q_n;
      // the port this cycle: a read first, else the oldest pending write, else the arriving
      wire             rd = iss_v;
      wire             from_q = !rd && (q_n != '0);
      wire             direct = !rd && (q_n == '0) && wr_en;
      wire             push = wr_en && !direct;
      wire             we = from_q || direct;
      wire  [AW-1:0]   addr = rd ? AW'(int'(iss_col) * G_MAX + int'(iss_g))
                            : from_q ? q_addr[0] : AW'(wr_addr);
      wire  [WORD-1:0] wdata = from_q ? q_data[0] : wr_data;
      always_ff @(posedge clk) begin
        if (en) begin
          if (we) mem[addr] <= wdata;
          else if (rd) rd_q <= mem[addr];
        end
      end
      always_ff @(posedge clk) begin
        if (rst) begin
          q_n <= '0;
        end else if (en) begin
          if (from_q)
            for (int i = 0; i < QD - 1; i++) begin
              q_addr[i] <= q_addr[i+1]; q_data[i] <= q_data[i+1];
            end
          if (push) begin
            q_addr[int'(q_n) - int'(from_q)] <= AW'(wr_addr);
            q_data[int'(q_n) - int'(from_q)] <= wr_data;
          end
          q_n <= q_n - QW'(from_q) + QW'(push);
        end
      end
      // a slot's reads take cycles t .. t + G - 1, its first write arrives in t + CU_T: the
      // writes waiting now must fit in the CU_T - G cycles between, none still computed
      logic computing;
      always_comb begin
        computing = 1'b0;
        for (int i = 0; i < CU_T - 1; i++) computing = computing || (cu_v[i] && cu_upd[i]);
      end
      wire [QW:0] waiting = (QW + 1)'(q_n) + (QW + 1)'(wr_en);
      wire [8:0]  gap = (CU_T > int'(ngroups)) ? 9'(CU_T - int'(ngroups)) : 9'd0;
      assign port_ok = !computing && (9'(waiting) <= gap);
    end
  endgenerate

  // ---- the row window and the row sum: tree(lg K_MAX + 1) cycles ----------------------------
  // the updated column sums are registered (end of the update) with the group's control
  logic            rs_v, rs_last, rs_fill, rs_emit;
  logic [GW-1:0]   rs_g;
  logic [CS_W-1:0] rs_new [LANES];
  always_ff @(posedge clk) begin
    if (rst) rs_v <= 1'b0;
    else if (en) rs_v <= cu_v[CU_T - 1];
    if (en) begin
      rs_g <= cu_g[CU_T - 1]; rs_last <= cu_last[CU_T - 1];
      rs_fill <= cu_fill[CU_T - 1]; rs_emit <= cu_emit[CU_T - 1];
      rs_new <= cs_new;
      if (cu_v[CU_T - 1])
        for (int i = 0; i < LANES; i++)
          if (int'(cu_g[CU_T - 1]) * LANES + i < D_MAX)
            newest[int'(cu_g[CU_T - 1]) * LANES + i] <= cs_new[i];
    end
  end
  // win[j][d]: the column sum j columns before the newest in the row window
  logic [CS_W-1:0] win [K_MAX][D_MAX];
  always_ff @(posedge clk) begin
    if (en && rs_v) begin
      for (int i = 0; i < LANES; i++) begin
        if (int'(rs_g) * LANES + i < D_MAX) begin
          for (int j = K_MAX - 1; j > 0; j--)
            win[j][int'(rs_g) * LANES + i] <= rs_fill ? rs_new[i]
                                                      : win[j-1][int'(rs_g) * LANES + i];
          win[0][int'(rs_g) * LANES + i] <= rs_new[i];
        end
      end
    end
  end

  logic [A_W-1:0] lane_sum [LANES];
  genvar l, kk;
  generate
    for (ln = 0; ln < LANES; ln++) begin : lane_rs
      for (l = 0; l <= RS_LEVELS; l++) begin : lvl
        localparam bit REG = (l > 0) && (l < RS_LEVELS) && (l % V == 0);
        logic [S_W-1:0] p [KN];   // node k of level l (KN >> l used); after the last: p[0]
        logic [S_W-1:0] c [KN];
        if (l == 0) begin : leaves  // the window after this column: [new, win[0], ...]
          for (kk = 0; kk < KN; kk++) begin : leaf
            if (kk == 0) begin : newest_col
              assign c[kk] = S_W'(rs_new[ln]);
            end else if (kk < K_MAX) begin : older_col   // used while kk < k
              always_comb begin
                int di;
                di = int'(rs_g) * LANES + ln;
                c[kk] = '0;
                if (kk < int'(k) && di < D_MAX)
                  c[kk] = S_W'(rs_fill ? rs_new[ln] : win[kk-1][di]);
              end
            end else begin : pad
              assign c[kk] = '0;
            end
          end
        end else if (l <= KL) begin : add
          for (kk = 0; kk < KN; kk++) begin : node
            if (kk < (KN >> l)) begin : live
              assign c[kk] = lvl[l-1].p[2*kk] + lvl[l-1].p[2*kk+1];
            end else begin : idle
              assign c[kk] = '0;
            end
          end
        end else begin : saturate   // min(sum, 2^A_W - 1)
          assign c[0] = (lvl[l-1].p[0] > S_W'((1 << A_W) - 1)) ? S_W'((1 << A_W) - 1)
                                                                 : lvl[l-1].p[0];
          for (kk = 1; kk < KN; kk++) begin : idle
            assign c[kk] = '0;
          end
        end
        if (REG) begin : pipe
          always_ff @(posedge clk) if (en) p <= c;
        end else begin : wire_
          assign p = c;
        end
      end
      assign lane_sum[ln] = A_W'(lvl[RS_LEVELS].p[0]);
    end
  endgenerate

  // the group's control through the tree's RS_T - 1 inner registers
  logic            rt_v [RS_T], rt_last [RS_T], rt_emit [RS_T];
  logic [GW-1:0]   rt_g [RS_T];
  assign rt_v[0] = rs_v; assign rt_last[0] = rs_last; assign rt_emit[0] = rs_emit;
  assign rt_g[0] = rs_g;
  genvar t;
  generate
    for (t = 1; t < RS_T; t++) begin : rs_pipe
      always_ff @(posedge clk) begin
        if (rst) rt_v[t] <= 1'b0;
        else if (en) rt_v[t] <= rt_v[t-1];
        if (en) begin
          rt_last[t] <= rt_last[t-1]; rt_emit[t] <= rt_emit[t-1]; rt_g[t] <= rt_g[t-1];
        end
      end
    end
  endgenerate

  // ---- the output register: each group's sums in place; valid with the slot's last group ----
  always_ff @(posedge clk) begin
    if (rst) begin
      out_valid <= 1'b0;
    end else if (en) begin
      out_valid <= rt_v[RS_T - 1] && rt_last[RS_T - 1] && rt_emit[RS_T - 1];
      if (rt_v[RS_T - 1])
        for (int i = 0; i < LANES; i++)
          if (int'(rt_g[RS_T - 1]) * LANES + i < D_MAX)
            agg[(int'(rt_g[RS_T - 1]) * LANES + i) * A_W +: A_W] <= lane_sum[i];
    end
  end
endmodule
