// Driver for bench/mase.py: times batches of trials of one MASE task, in one JVM.
//
// Compiled by bench/mase.py against a checkout of the authors' MASE (fd13449); it
// sits in MASE's package mase.mason because MASE's evaluation hooks (preSimulation,
// evaluationStep, postSimulation) are package-visible there.
//
// What it does is MASE's own trial loop (MasonSimulator.evaluateSolution), repeated
// for random genomes, with the steps every trial took counted:
//   - the simulator comes from the parameter file as MASE's MasonPlayer builds it
//     (ec.Evolve.loadParameterDatabase, ec.Evolve.initialize, eval.problem or
//     eval.base.problem);
//   - each genome is a controller decoded as NeuralControllerIndividual does
//     (an encog FlatNetwork: linear inputs with bias, sigmoid hidden and output
//     units), shared by the team (HomogeneousGroupController);
//   - a genome's trials run in one MaseSimState, each with fresh clones of the
//     parameter file's evaluation functions (fitness, task-specific
//     characterisation, and the SystematicEvaluator when syseval.params is layered
//     in), stepped with the simulation; their results are merged as MASE merges
//     them.
//
// Protocol: after start-up and --warmup batches, every line "run" on stdin runs one
// batch of --genomes genomes x --trials trials and prints one line
//   "batch trial_steps=N cpu_ns=C wall_ns=W"
// where N sums the steps of every trial, C is the process CPU time (JIT and GC
// threads included) and W the wall time of the batch. "quit" ends the process.

package mase.mason;

import ec.EvolutionState;
import ec.Evolve;
import ec.Evaluator;
import ec.util.Parameter;
import ec.util.ParameterDatabase;
import java.io.BufferedReader;
import java.io.InputStreamReader;
import java.lang.management.ManagementFactory;
import java.lang.reflect.Field;
import java.util.Random;
import mase.MetaEvaluator;
import mase.SimulationProblem;
import mase.controllers.GroupController;
import mase.controllers.HomogeneousGroupController;
import mase.controllers.NeuralAgentController;
import mase.evaluation.EvaluationFunction;
import mase.evaluation.EvaluationResult;
import org.encog.engine.network.activation.ActivationFunction;
import org.encog.engine.network.activation.ActivationLinear;
import org.encog.engine.network.activation.ActivationSigmoid;
import org.encog.neural.flat.FlatLayer;
import org.encog.neural.flat.FlatNetwork;

public final class MaseBench {

    private final MasonSimulator simulator;
    private final EvaluationFunction[] evalFunctions;
    private final FlatNetwork prototype;
    private final int genomeSize;
    private final Random random;
    private final com.sun.management.OperatingSystemMXBean os;

    private MaseBench(String paramsFile, long seed) throws Exception {
        String[] args = {"-file", paramsFile};
        ParameterDatabase db = Evolve.loadParameterDatabase(args);
        EvolutionState state = Evolve.initialize(db, 0);
        Parameter base = new Parameter(EvolutionState.P_EVALUATOR).push(Evaluator.P_PROBLEM);
        if (!db.exists(base, null)) {
            base = new Parameter(EvolutionState.P_EVALUATOR)
                    .push(MetaEvaluator.P_BASE_EVAL).push(Evaluator.P_PROBLEM);
        }
        simulator = (MasonSimulator) db.getInstanceForParameter(base, null, MasonSimulator.class);
        simulator.setup(state, base);
        Field f = SimulationProblem.class.getDeclaredField("evalFunctions");
        f.setAccessible(true);
        evalFunctions = (EvaluationFunction[]) f.get(simulator);

        int input = db.getInt(new Parameter("neural.input"), null);
        int hidden = db.getInt(new Parameter("neural.hidden"), null);
        int output = db.getInt(new Parameter("neural.output"), null);
        String structure = db.getStringWithDefault(new Parameter("neural.structure"), null, "feed-forward");
        if (!structure.equalsIgnoreCase("feed-forward") || db.getBoolean(new Parameter("neural.tanh"), null, false)) {
            throw new IllegalArgumentException("MaseBench handles feed-forward sigmoid networks only");
        }
        ActivationFunction linear = new ActivationLinear();
        ActivationFunction sigmoid = new ActivationSigmoid();
        FlatLayer[] layers = hidden == 0
                ? new FlatLayer[]{
                    new FlatLayer(linear, input, FlatNetwork.DEFAULT_BIAS_ACTIVATION),
                    new FlatLayer(sigmoid, output, FlatNetwork.NO_BIAS_ACTIVATION)}
                : new FlatLayer[]{
                    new FlatLayer(linear, input, FlatNetwork.DEFAULT_BIAS_ACTIVATION),
                    new FlatLayer(sigmoid, hidden, FlatNetwork.DEFAULT_BIAS_ACTIVATION),
                    new FlatLayer(sigmoid, output, FlatNetwork.NO_BIAS_ACTIVATION)};
        prototype = new FlatNetwork(layers);
        genomeSize = prototype.getWeights().length;
        int declared = db.getInt(new Parameter("vector.species.genome-size"), null);
        if (declared != genomeSize) {
            throw new IllegalArgumentException("genome-size " + declared + " but the network has "
                    + genomeSize + " weights");
        }
        random = new Random(seed);
        os = (com.sun.management.OperatingSystemMXBean) ManagementFactory.getOperatingSystemMXBean();
    }

    private GroupController randomController() {
        double[] genome = new double[genomeSize];
        for (int i = 0; i < genomeSize; i++) {
            genome[i] = 2.0 * random.nextDouble() - 1.0;  // vector.species min/max-gene
        }
        FlatNetwork network = prototype.clone();
        network.decodeNetwork(genome);
        return new HomogeneousGroupController(new NeuralAgentController(network));
    }

    /** MasonSimulator.evaluateSolution for one genome, counting the steps taken. */
    private long evaluate(GroupController gc, long seed, int trials, Object[] sink) {
        MaseSimState sim = simulator.createSimState(gc, seed);
        EvaluationResult[][] results = new EvaluationResult[evalFunctions.length][trials];
        long steps = 0;
        for (int r = 0; r < trials; r++) {
            MasonEvaluation[] evals = new MasonEvaluation[evalFunctions.length];
            for (int i = 0; i < evalFunctions.length; i++) {
                evals[i] = (MasonEvaluation) evalFunctions[i].clone();
                evals[i].setSimulationModel(sim);
            }
            sim.start();
            for (MasonEvaluation e : evals) {
                e.preSimulation();
            }
            while (sim.schedule.getSteps() < simulator.maxSteps) {
                boolean more = sim.schedule.step(sim);
                for (MasonEvaluation e : evals) {
                    e.evaluationStep();
                }
                if (!more) {
                    break;
                }
            }
            steps += sim.schedule.getSteps();
            for (int i = 0; i < evals.length; i++) {
                evals[i].postSimulation();
                results[i][r] = evals[i].getResult();
            }
            sim.finish();
        }
        for (int i = 0; i < evalFunctions.length; i++) {
            sink[i] = results[i][0].mergeEvaluations(results[i]);
        }
        return steps;
    }

    private String batch(int genomes, int trials) {
        Object[] sink = new Object[evalFunctions.length];
        long cpu0 = os.getProcessCpuTime();
        long wall0 = System.nanoTime();
        long steps = 0;
        for (int g = 0; g < genomes; g++) {
            steps += evaluate(randomController(), random.nextLong(), trials, sink);
        }
        long wall = System.nanoTime() - wall0;
        long cpu = os.getProcessCpuTime() - cpu0;
        return "batch trial_steps=" + steps + " cpu_ns=" + cpu + " wall_ns=" + wall
                + " evaluations=" + evalFunctions.length;
    }

    public static void main(String[] args) throws Exception {
        String params = null;
        int genomes = 200, trials = 10, warmup = 1;
        long seed = 0;
        for (int i = 0; i < args.length; i++) {
            switch (args[i]) {
                case "--params" -> params = args[++i];
                case "--genomes" -> genomes = Integer.parseInt(args[++i]);
                case "--trials" -> trials = Integer.parseInt(args[++i]);
                case "--warmup" -> warmup = Integer.parseInt(args[++i]);
                case "--seed" -> seed = Long.parseLong(args[++i]);
                default -> throw new IllegalArgumentException("unknown argument " + args[i]);
            }
        }
        if (params == null) {
            throw new IllegalArgumentException("--params FILE is required");
        }
        MaseBench bench = new MaseBench(params, seed);
        for (int w = 0; w < warmup; w++) {
            bench.batch(genomes, trials);
        }
        System.out.println("ready evaluations=" + bench.evalFunctions.length);
        System.out.flush();
        BufferedReader in = new BufferedReader(new InputStreamReader(System.in));
        String line;
        while ((line = in.readLine()) != null) {
            line = line.trim();
            if (line.equals("quit")) {
                break;
            }
            if (line.equals("run")) {
                System.out.println(bench.batch(genomes, trials));
                System.out.flush();
            }
        }
    }
}
